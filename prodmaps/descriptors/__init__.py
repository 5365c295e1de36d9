"""Point descriptors, one module each: spectral (HKS, WKS, heat kernels), SHOT, AWFT.

``prodmaps.descriptors.hks`` etc. are re-exported here; see :mod:`.spectral`, :mod:`.histograms` and
:mod:`.windowed_fourier` for the definitions and conventions. Curvatures live in :mod:`prodmaps.curvature`,
the anisotropic Laplacian in :mod:`prodmaps.operators`.
"""

from .histograms import SHOT_DIM, shot
from .spectral import (
                       ZERO_EIGENVALUE_REL,
                       heat_kernel,
                       hks,
                       hks_times,
                       wks,
                       wks_energies,
                       wks_energies_from_evals,
                       wks_weights,
)
from .windowed_fourier import GEOVEC_BANDS, awft, geometry_vectors

__all__ = ["hks", "hks_times", "wks", "wks_energies", "wks_energies_from_evals", "wks_weights",
           "heat_kernel", "shot", "awft", "geometry_vectors", "GEOVEC_BANDS", "SHOT_DIM", "ZERO_EIGENVALUE_REL"]
