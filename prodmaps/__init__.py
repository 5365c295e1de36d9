"""prodmaps: functional maps with product preservation.

A reproducible implementation of D. Nogneng, S. Melzi, E. Rodolà, U. Castellani, M. Bronstein,
M. Ovsjanikov, "Improved Functional Mappings via Product Preservation", Computer Graphics Forum
(Eurographics) 2018.

Conventions (see each module for details): bases are A-orthonormal (area inner product) with the
constant first; ``k`` counts the constant (the paper's ``k_M = 9`` is ``eigenbasis(mesh, 10)``);
``C_12`` is ``(k2, k1)`` and maps coefficients on shape 1 to shape 2; ``p2p_21`` is ``(n2,)``.

Importing prodmaps loads numpy and scipy only.
"""

__version__ = "0.1.0"

from .mesh import Mesh, MeshError
from .io import load_mesh, save_mesh
from .laplacian import laplacian
from .basis import Basis, eigenbasis, fourier_basis
from .products import ProductBasis, product_basis
from .approx import ApproximationOperator, approximate, operator
from .transfer import extend_fmap, fmap_from_p2p, transfer
from .metrics import area_fraction_curve, relative_error
from . import mesh, io, basis, products, approx, metrics, datasets, geodesics, descriptors, functions, fmaps, p2p, lmh, truncation

__all__ = [
    "Mesh", "MeshError", "load_mesh", "save_mesh", "laplacian", "Basis", "eigenbasis",
    "fourier_basis", "ProductBasis", "product_basis", "ApproximationOperator", "approximate",
    "operator", "extend_fmap", "fmap_from_p2p", "transfer", "area_fraction_curve", "relative_error",
]
