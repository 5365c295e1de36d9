"""Preparing datasets the package may not ship: FAUST and TOSCA, and derived meshes.

FAUST and TOSCA come from the user's own download; derived meshes have a different connectivity
(with their ground-truth maps).

One module each: :mod:`.archive` (safe archive reading — nothing extracted under its own name,
zip-slip and zip-bomb refused — and atomic output), :mod:`.faust`, :mod:`.tosca`,
:mod:`.variants`. Run them as ``python -m prodmaps.prepare faust|tosca|variants ...`` or through
the thin scripts in the repository's ``data_scripts/``. Prepared datasets go to
:func:`prodmaps.datasets.data_root` (``$PRODMAPS_DATA``, else ``~/.local/share/prodmaps``).
"""
