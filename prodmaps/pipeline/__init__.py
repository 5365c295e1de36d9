"""The reproduction pipeline: run the paper's notebooks, hash, diff, report.

Layer 3 of the package (it runs notebooks and reads their results; nothing in the math library
or :mod:`prodmaps.experiments` imports it, and its code does not enter the run hashes). The
notebooks import one function of it, :func:`.registry.run_parameters`, which reads their profile
values from the registry: the same values the runner hands them as papermill parameters, which
do enter the hashes.

:mod:`.registry`    ``paper/runs.toml``: which notebook reproduces which figure, with which parameters
:mod:`.hashing`     what a run's outputs depend on (notebook, parameters, importable code, data)
:mod:`.notebooks`   declared parameters, output stripping, HTML export
:mod:`.execute`     resumable, failure-isolated batch execution with papermill
:mod:`.schedulers`  this process, a local process pool, or a Dask cluster
:mod:`.baselines`   the committed smoke baselines
:mod:`.diffing`     numbers with per-key tolerances, images by pixel RMS
:mod:`.report_data` the report's data: one :class:`~.report_data.DatasetReport` per dataset (results or JSON)
:mod:`.report`      the report's document assembled from that data; ``build_report`` writes it
:mod:`.main_text`   the report's main text: summary, glossary, claims, tables, forking paths
:mod:`.appendices`  the report's appendices: figure gallery, studies, one per dataset, runs
:mod:`.prose`       the paper's prose of the report, read from ``paper/report_text/``
:mod:`.links`       folders and links as the report names them
:mod:`.forking`     the report's forking paths: each open reading, chosen on FAUST, checked on the others
:mod:`.document`    the document model, rendered to Markdown and HTML
:mod:`.publishing`  a complete paper run into the committed ``paper/REPORT.md`` / ``.html``
:mod:`.gallery`     the documentation site's gallery and report page
:mod:`.cli`         ``prodmaps reproduce | diff | report | publish | claims``
"""
