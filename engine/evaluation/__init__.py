"""Scoring segmentations against ground truth with the DAVIS measures.

:func:`region_similarity` (J, the Jaccard index), :func:`boundary_measure`
(F, the boundary F-measure) and :func:`statistics` (mean, recall, decay) as
the DAVIS evaluation toolkit defines them (``davis2017-evaluation``,
``davis2017/metrics.py`` and ``utils.db_statistics``); :func:`score_sequence`
applies the DAVIS protocol to one sequence (its first and last frame left
out).  Masks are H x W arrays, non-zero = object.
"""

from engine.evaluation.davis import (
    BOUNDARY_TOLERANCE,
    SequenceScore,
    Statistics,
    boundary_map,
    boundary_measure,
    region_similarity,
    score_sequence,
    statistics,
)

__all__ = [
    "BOUNDARY_TOLERANCE",
    "SequenceScore",
    "Statistics",
    "boundary_map",
    "boundary_measure",
    "region_similarity",
    "score_sequence",
    "statistics",
]
