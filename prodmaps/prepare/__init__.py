"""Preparing datasets the package may not ship: FAUST and TOSCA, their remeshed collections, derived meshes.

FAUST and TOSCA come from the user's own download; FAUST_r and TOSCA_r from a clone of their public
repository (``llorz/SGA18_orientation_BCICP_dataset``, the licences of FAUST and TOSCA apply);
derived meshes have a different connectivity (with their ground-truth maps).

One module each: :mod:`.archive` (safe archive reading — nothing extracted under its own name,
zip-slip and zip-bomb refused — and atomic output), :mod:`.faust`, :mod:`.tosca`, :mod:`.sga18`
(``faust_r``, ``tosca_r``, ``tosca_r_noniso``), :mod:`.variants`. Run them as
``python -m prodmaps.prepare faust|tosca|faust_r|tosca_r|tosca_r_noniso|variants ...`` (FAUST and
TOSCA also through the thin scripts in the repository's ``data_scripts/``). Prepared datasets go to
:func:`prodmaps.datasets.data_root` (``$PRODMAPS_DATA``, else ``~/.local/share/prodmaps``).
"""
