"""prodmaps: functional maps with product preservation.

A reproducible implementation of D. Nogneng, S. Melzi, E. Rodolà, U. Castellani, M. Bronstein,
M. Ovsjanikov, "Improved Functional Mappings via Product Preservation", Computer Graphics Forum
(Eurographics) 2018.

Three layers, arrows pointing down only:

* the math library (this package's modules: meshes and I/O, spectral bases, products and
  approximation, maps and point maps, descriptors, fields, geodesics, metrics, datasets);
* :mod:`prodmaps.experiments`: what the paper's notebooks share (cached per-shape data, maps,
  function families, the table protocol, claims);
* :mod:`prodmaps.pipeline`: batch reproduction, hashing, baselines, diffing, report, CLI.

The conventions (bases A-orthonormal with the constant first, ``k`` counts the constant,
``C_12`` is ``(k2, k1)``, ``p2p_21`` is ``(n2,)``) are stated once in :mod:`prodmaps.conventions`.

No module shares its name with a function: ``pm.transfer``, ``pm.transfer_operator`` and
``pm.laplacian`` are functions, defined in :mod:`prodmaps.transfers` and
:mod:`prodmaps.operators`. Importing prodmaps loads numpy and scipy only.
"""

__version__ = "0.3.0"

from . import (  # noqa: F401
               approx,
               basis,
               cache,
               checks,
               conventions,
               curvature,
               datasets,
               descriptors,
               eigensolver,
               errors,
               fields,
               fmaps,
               geodesics,
               io,
               lmh,
               mapping,
               mesh,
               metrics,
               operators,
               p2p,
               plotting,
               pointcloud,
               products,
               progress,
               sampling,
               storage,
               transfers,
               truncation,
)
from .approx import ApproximationOperator, approximate, approximation_operator
from .basis import Basis, eigenbases, eigenbasis, fourier_basis, load_basis
from .errors import MeshError, MeshWarning, NeedsFacesError
from .io import load_mesh, load_point_cloud, save_mesh
from .mapping import extend_fmap, fmap_from_p2p
from .mesh import Mesh
from .metrics import area_fraction_curve, relative_error
from .operators import laplacian
from .plotting import plot, plot_map
from .pointcloud import PointCloud
from .products import ProductBasis, product_basis
from .storage import load_map, save_map
from .transfers import (
               TransferOperator,
               transfer,
               transfer_operator,
)

__all__ = [
    "Mesh", "MeshError", "MeshWarning", "NeedsFacesError", "PointCloud", "load_mesh", "load_point_cloud", "save_mesh",
    "laplacian", "Basis", "eigenbasis", "eigenbases", "fourier_basis", "load_basis", "ProductBasis", "product_basis",
    "ApproximationOperator", "approximate", "approximation_operator", "extend_fmap", "fmap_from_p2p",
    "transfer_operator", "TransferOperator", "transfer", "save_map", "load_map", "area_fraction_curve",
    "relative_error", "plot", "plot_map",
]
