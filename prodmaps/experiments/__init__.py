"""The experiments layer: one module (or package) per notebook, named after it, over a shared part.

``notebooks/<name>.ipynb`` calls ``prodmaps.experiments.<name>``: what that notebook computes
(``fig07_function_transfer``, ``tables_transfer``, ``study_normalization``, ...; Figure 14's is
the package ``fig14_quad_transfer``). What several notebooks use lives in
:mod:`prodmaps.experiments.shared`: per-shape caches (``store``), function families
(``families``), ground-truth and NO17 maps (``maps``), the transfer protocol of the tables
(``protocol``), worker processes (``parallel``), the tie rule (``compare``), the published tables
(``published``), results files and figures (``results``, ``render``), the claims ledger
(``claims``) and helpers of two figures (``reconstruction``, ``composite``).

Arrows point down only: notebooks -> these modules -> :mod:`prodmaps`; nothing here imports
:mod:`prodmaps.pipeline` (``tests/library/test_imports.py`` checks it), and a notebook module
imports only the shared part and the library (Figure 14 reads Figure 12/13's conversions).
Importing this package imports nothing.

The paper's ``k_M`` / ``k_N`` (and ``k``, ``ks``) in the notebooks' parameters and in these
modules' arguments count the non-constant functions: a basis of ``k_M + 1`` columns in the
library, whose ``k`` counts the constant. A count of columns with the constant is named
``*_dim`` here (``source_dim``, ``target_dims``, ``target_dim``, ``mh_dim``) or ``n_eig``.
Every transfer goes through the registry of :mod:`prodmaps.transfers`; the tables' columns are
``{label: (registry method, parameters)}`` (:data:`prodmaps.experiments.shared.protocol.PAPER_COLUMNS`).
Adding a run: ``docs/guide/adding_a_run.md``.
"""
