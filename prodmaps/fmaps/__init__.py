"""Functional maps: the NO17 energy and its solvers, ZoomOut, the NO17 demo descriptors.

One module per concept: :mod:`.no17` (energy, quadratic form, L-BFGS and direct solvers),
:mod:`.refinement` (ZoomOut), :mod:`.icp`, :mod:`.demo` (pyFM's NO17 demo descriptors). The conventions (``C_12`` is
``(k2, k1)``, ``p2p_21`` pulls back, ``k`` counts the constant) are those of
:mod:`prodmaps.conventions`.
"""

from ..sampling import farthest_point_landmarks
from .demo import no17_demo_descriptors
from .icp import icp_refine
from .no17 import (
                   NO17Terms,
                   energy_and_gradient,
                   first_column,
                   fit_no17,
                   laplacian_mask,
                   multiplication_operators,
                   no17_terms,
                   quadratic_form,
)
from .refinement import zoomout

__all__ = ["first_column", "laplacian_mask", "multiplication_operators", "NO17Terms",
           "no17_terms", "energy_and_gradient", "quadratic_form", "fit_no17", "zoomout", "icp_refine",
           "no17_demo_descriptors", "farthest_point_landmarks"]
