"""Progress bars for long work: a tqdm bar when interactive, silence otherwise.

One home for the rule every long computation of the library follows (point-map conversion,
eigenbases of large shapes, NO17, ZoomOut): ``progress=None`` (their default) shows a bar only
when the work is long (``work > min_work``) and standard error is a terminal; ``True`` always
shows one (tqdm when installed, plain lines otherwise); ``False`` never does.
"""

from __future__ import annotations

import sys

__all__ = ["progress_bar", "wants_progress", "NullBar"]


class NullBar:
    """A bar that shows nothing (``update`` and ``close`` do nothing); usable as a context manager."""

    n = 0

    def update(self, k: int = 1) -> None:
        """Advance by ``k`` (counted, nothing shown)."""
        self.n += k

    def close(self) -> None:
        """Nothing to close."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


class _Lines(NullBar):
    """Plain progress lines on ``stream`` (no tqdm)."""

    def __init__(self, total: int | None, desc: str, unit: str, stream):
        self.total, self.desc, self.unit, self.stream = total, desc, unit, stream

    def update(self, k: int = 1) -> None:
        """Advance by ``k`` and print a line."""
        self.n += k
        of = "" if self.total is None else f"/{self.total}"
        print(f"{self.desc}: {self.unit} {self.n}{of}", file=self.stream, flush=True)


def wants_progress(progress: bool | None, work: float = 0.0, min_work: float = 0.0, stream=None) -> bool:
    """Whether to show a bar: ``progress`` if given, else long work on an interactive stream.

    Examples
    --------
    >>> wants_progress(True), wants_progress(False, work=1e30)
    (True, False)
    >>> wants_progress(None, work=1.0, min_work=10.0)  # short work: silent
    False
    """
    if progress is not None:
        return bool(progress)
    stream = sys.stderr if stream is None else stream
    return work > min_work and bool(getattr(stream, "isatty", lambda: False)())


def progress_bar(total: int | None, desc: str, *, progress: bool | None = None, work: float = 0.0,
                 min_work: float = 0.0, unit: str = "step", stream=None):
    """A progress bar of ``total`` steps on ``stream`` (stderr), or a :class:`NullBar` when silent.

    Parameters
    ----------
    total : number of steps, or ``None`` when unknown (a counter without an end).
    desc : what is being done (the bar's label).
    progress : ``True`` always, ``False`` never, ``None`` (default) when ``work > min_work`` and
        ``stream`` is a terminal (:func:`wants_progress`).
    work, min_work : the size of the work (e.g. multiply-adds) and the size from which it is long.
    unit : the name of a step.
    stream : where the bar goes (default ``sys.stderr``).

    Returns
    -------
    object with ``update(k=1)`` and ``close()``: a tqdm bar (tqdm installed), plain lines (no
    tqdm), or a silent :class:`NullBar`.

    Examples
    --------
    >>> bar = progress_bar(3, "demo", progress=False)
    >>> bar.update(); bar.close(); type(bar).__name__
    'NullBar'
    """
    stream = sys.stderr if stream is None else stream
    if not wants_progress(progress, work, min_work, stream):
        return NullBar()
    try:
        from tqdm import tqdm
    except ImportError:
        return _Lines(total, desc, unit, stream)
    return tqdm(total=total, desc=desc, unit=unit, file=stream, dynamic_ncols=True)
