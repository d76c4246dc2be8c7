"""The paper's physics: a chain of masses and springs and its equilibrium.

Krinidis & Pitas, "2D Physics-Based Deformable Shape Models: Explicit
Governing Equations" (docs/math.md has the equations as implemented here):
the system matrix (I + K) of a closed ring or open line (eq. 13-16), the
Green's function in its stable form (eq. 18-20, EFDM), its truncation
(eq. 21, EFDMT), the modal reference (DMMA, DMMAT), the exact O(N) solver
(beyond the paper), :func:`deform` over all of them, and :class:`Chain`
with static and dynamic updates.  Imports no OpenCV and, until a solver
first runs, no compiler.  Coordinates are ``[x, y]`` pixels.
"""

from engine.physics._validation import METHODS, MODAL_METHODS
from engine.physics.chain import Chain, ChainState
from engine.physics.deform import deform
from engine.physics.green import green_kernel, literal_kernel, paper_radius, tolerance_radius
from engine.physics.matrices import laplacian, stiffness_matrix, system_matrix
from engine.physics.recursive import solve_exact, warm_up

__all__ = [
    "METHODS",
    "MODAL_METHODS",
    "Chain",
    "ChainState",
    "deform",
    "green_kernel",
    "laplacian",
    "literal_kernel",
    "paper_radius",
    "solve_exact",
    "stiffness_matrix",
    "system_matrix",
    "tolerance_radius",
    "warm_up",
]
