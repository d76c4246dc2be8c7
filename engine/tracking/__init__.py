"""Tracking: follow an object's boundary through video with the chain's physics.

:class:`Tracker` orchestrates four swappable stages, each behind a
``typing.Protocol`` of :mod:`engine.tracking.stages` (:class:`MotionModel`,
:class:`AppearanceModel`, :class:`BoundaryCues`, :class:`Segmentation`), and
refines the contour as the chain's equilibrium under the image forces
(:func:`refine`) before the joint band segmentation.  The default stages are
:class:`FlowMotion`, :class:`ColourHistogram`, :class:`RegionEdgeCues` and
:class:`BandCut`.  :func:`pack_image` and :func:`unpack_image` are the lossless text
form in which states keep a frame.  Imports OpenCV (``import engine`` does not).
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from engine.tracking._state_codec import pack_image, unpack_image
from engine.tracking._warm import warm_up
from engine.tracking.appearance import ColourHistogram
from engine.tracking.cues import RegionEdgeCues
from engine.tracking.maps import Maps
from engine.tracking.objects import ObjectResult, ObjectsTracker, label_mask
from engine.tracking.options import TrackerOptions
from engine.tracking.pieces import PiecesResult, PiecesTracker
from engine.tracking.prediction import FlowMotion
from engine.tracking.refinement import Refinement, refine
from engine.tracking.segmentation import BandCut
from engine.tracking.stages import (
    AppearanceModel,
    BoundaryCues,
    MotionModel,
    Prediction,
    Segmentation,
)
from engine.tracking.tracker import Tracker, TrackResult

__all__ = [
    "AppearanceModel",
    "BandCut",
    "BoundaryCues",
    "ColourHistogram",
    "FlowMotion",
    "Maps",
    "MotionModel",
    "ObjectResult",
    "ObjectsTracker",
    "PiecesResult",
    "PiecesTracker",
    "Prediction",
    "Refinement",
    "RegionEdgeCues",
    "Segmentation",
    "TrackResult",
    "Tracker",
    "TrackerOptions",
    "label_mask",
    "pack_image",
    "refine",
    "unpack_image",
    "warm_up",
]
