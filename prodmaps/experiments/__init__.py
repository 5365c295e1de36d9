"""The experiments layer: what the paper's notebooks share (importing this package imports nothing).

Arrows point down only: the notebooks import these modules, these modules import the math library
(:mod:`prodmaps`), never :mod:`prodmaps.pipeline` (``tests/library/test_imports.py`` checks it).
The paper's ``k_M`` / ``k_N`` (and ``k``, ``ks``) in the notebooks' parameters and in these
modules' arguments count the non-constant functions: a basis of ``k_M + 1`` columns in the
library, whose ``k`` counts the constant. A count of columns with the constant is named
``*_dim`` here (``source_dim``, ``target_dims``, ``target_dim``, ``mh_dim``) or ``n_eig``.

Index: which notebook (``notebooks/<name>.ipynb``) imports which module
-----------------------------------------------------------------------
* :mod:`.results` (``results.json``, repeatable PNG figures), :mod:`.claims` (the claims ledger,
  ``claims.toml``, and its rules): every notebook.
* :mod:`.store` (per-shape meshes, bases, descriptors, maps; disk-cached): fig08_area_curves,
  fig12_13_p2p, tables_transfer, study_default_transfer, study_family_readings, study_no17,
  study_normalization, study_truncation.
* :mod:`.families` (the nine function families of Section 5.1): fig08_area_curves,
  tables_transfer, study_default_transfer, study_family_readings, study_truncation.
* :mod:`.render` (off-screen pyvista renders): fig04, fig05, fig06, fig07, fig09, fig10, fig14,
  howto_own_meshes.
* :mod:`.fourier` (the 1D Fourier basis and its products): fig02_fourier_products,
  fig03_fourier_indicator.
* :mod:`.reconstruction` (functions represented with and without products):
  fig04_coordinate_reconstruction, fig05_higher_order, fig06_indicator_region, fig10_lmh.
* :mod:`.composite` (a composite function transferred, std vs products): fig07_function_transfer,
  fig09_remeshing.
* :mod:`.protocol` (the transfer protocol, pairs x sizes x methods): fig08_area_curves; and
  through :mod:`.tables` and the studies, tables_transfer and study_*.
* :mod:`.convergence` (HKS and WKS as the target basis grows): fig11_hks_wks_convergence.
* :mod:`.pointmaps` (point maps from a functional map, std vs extended): fig12_13_p2p.
* :mod:`.crossfields`, :mod:`.crossfield_plots`, :mod:`.quads` (cross fields through a map, their
  plots, quad meshes through point maps): fig14_quad_transfer.
* :mod:`.howto` (demo files and user inputs): howto_own_meshes.
* :mod:`.tables` (Tables 1–6, the published values beside ours): tables_transfer.
* :mod:`.default_study`: study_default_transfer. :mod:`.family_readings`: study_family_readings.
  :mod:`.maps` (ground-truth and computed NO17 maps) and :mod:`.no17_study`: study_no17 (the maps
  also through :mod:`.store`). :mod:`.normalization_study`: study_normalization.
  :mod:`.truncation_study`: study_truncation.
* No notebook directly: :mod:`.compare` (one rule for every better / worse / tie; claims,
  composite, default_study, pointmaps), :mod:`.parallel` (pairs in worker processes; protocol,
  no17_study, crossfields), :mod:`.published` (the published tables; tables and the studies).
"""
