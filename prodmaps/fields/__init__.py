"""Tangent fields through functional maps: consistent cross fields and quad layouts (Figure 14).

The paper's Section 5.4 adapts [ACBCO17]: cross fields on two surfaces are related through
their action on real-valued functions, transported by a functional map; the paper's change is
to let that transport use the extended basis (``C~``, products of basis functions). This
subpackage implements the pieces on plain arrays:

* :mod:`.frames` — face frames, complex tangent coordinates, transport, complex gradients.
* :mod:`.crossfield` — ``N``-direction fields as power fields: connection Laplacian, smoothest
  and curvature-aligned fields [KCPS13], singularities and indices, angles modulo ``2π/N``,
  push-forward through a point map (evaluation only).
* :mod:`.operators` — the degree-N action of a cross field on functions, and the span Approach B
  keeps in an extended basis.
* :mod:`.consistency` — the consistency energy through ``C`` or ``C~`` and the design of a
  target field (or both) by linear least squares.
* :mod:`.quadmesh` — an integer-grid parametrisation along a cross field (libigl's comb,
  mismatch and cut, consistent rounding along the tree of cut chains, scipy solves) and its quad
  mesh: the cells of the integer iso-lines, one polygon closing each hole next to a singularity
  cluster (watertight on a closed input).

What follows [ACBCO17] and what is this package's own: the Figure 14 notebook and
``docs/guide/fields.md`` (the consistency model and the quad pipeline); the experiment and its figures:
:mod:`prodmaps.experiments.fig14_quad_transfer.crossfields` and :mod:`prodmaps.experiments.fig14_quad_transfer.plots`.

Conventions (the maps' and bases': :mod:`prodmaps.conventions`): face frames ``(u, v, n)`` with
``u`` the unit edge ``F[:,0] -> F[:,1]``; fields are complex per face in those frames; a cross
field is stored as its 4th power; the experiment's ``k`` is the paper's (non-constant functions).
"""

from .consistency import ConsistencyProblem, consistency_problem, design_consistent_field, design_joint
from .crossfield import (
    aligned_field,
    angle_stats,
    closest_point_correspondence,
    connection_laplacian,
    cross_angle,
    cross_field,
    curvature_guide,
    field_vectors,
    normalize_field,
    pushforward_field,
    pushforward_field_barycentric,
    rotate_field,
    singularities,
    singularity_index,
    smoothest_field,
    vertex_power_field,
)
from .frames import (
    Frames,
    angle_defect,
    as_frames,
    complex_gradient,
    face_to_vertex,
    mesh_frames,
    polygon_corner_degrees,
    tangent_frames,
    to_complex,
    to_vectors,
    vertex_holonomy,
)
from .operators import SpanProjector, field_action, powered_gradients, span_projector
from .quadmesh import close_holes, extract_quads, quad_mesh_stats, seamless_parametrization

__all__ = [
    "Frames", "tangent_frames", "mesh_frames", "as_frames", "to_complex", "to_vectors", "complex_gradient",
    "face_to_vertex", "angle_defect", "vertex_holonomy",
    "polygon_corner_degrees",
    "connection_laplacian", "smoothest_field", "curvature_guide", "aligned_field", "cross_field",
    "normalize_field", "rotate_field", "field_vectors", "cross_angle", "angle_stats", "singularity_index",
    "singularities", "vertex_power_field", "pushforward_field",
    "pushforward_field_barycentric", "closest_point_correspondence",
    "SpanProjector", "span_projector", "field_action", "powered_gradients",
    "ConsistencyProblem", "consistency_problem", "design_consistent_field", "design_joint",
    "seamless_parametrization", "extract_quads", "close_holes", "quad_mesh_stats",
]
