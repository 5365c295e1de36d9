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
:mod:`.report`      ``paper/REPORT.md`` / ``.html``
:mod:`.cli`         ``prodmaps reproduce | diff | report | claims``
"""
