"""Folders and links as the report names them.

Links are relative to the report's folder (:func:`relative_path`), so the Markdown and the HTML
page beside it work wherever the folder is moved. A results folder is named relative to the
project (:func:`shown_folder`); a published report (no machine paths) names a folder outside it
``<out>/...`` and quotes tracebacks without this machine's paths (:func:`without_machine_paths`).
A run's notebook is linked as executed, or in a published report as committed
(:func:`notebook_link`); a file that does not exist is named without a link.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from .registry import project_root

__all__ = ["relative_path", "shown_folder", "without_machine_paths", "notebook_link"]


def relative_path(path: Path, start: Path) -> str:
    """``path`` relative to the folder ``start``, with forward slashes (both resolved first).

    Examples
    --------
    >>> relative_path("/results/paper/fig02/a.png", "/results/paper/report")
    '../fig02/a.png'
    """
    return Path(os.path.relpath(Path(path).resolve(), Path(start).resolve())).as_posix()


def shown_folder(path: Path, base: Path | None, registry=None, out_root: Path | None = None) -> str:
    """A folder relative to the project (``results/paper/fig02``), else to ``base``, else as given.

    With ``out_root`` (a published report: no machine path), a folder outside the project is named
    ``<out>/`` and its path below ``out_root`` (``<out>/paper/fig02``) instead.
    """
    try:
        return Path(path).resolve().relative_to(project_root(registry)).as_posix()
    except ValueError:  # RegistryError is a ValueError: no project found
        pass
    if out_root is not None:
        try:
            return "<out>/" + Path(path).resolve().relative_to(Path(out_root).resolve()).as_posix()
        except ValueError:
            return f"<out>/{Path(path).name}"
    return str(path) if base is None else relative_path(path, base)


def without_machine_paths(text: str, registry=None) -> str:
    """A traceback for a committed report: project paths relative, ``<site-packages>/...``, others ``…/<file>``."""
    text = re.sub(r"(?:/[^\s/\"':,]+)+/(site-packages|dist-packages)/", r"<\1>/", text)
    try:
        text = text.replace(str(project_root(registry).resolve()) + "/", "")
    except ValueError:  # no project
        pass
    return re.sub(r"(?<![\w.<>~/:-])/(?:[^\s/\"':,]+/)+([^\s/\"':,]+)", r"…/\1", text)  # not in a URL


def _link(path: Path, base: Path, text: str) -> str:
    return f"[{text}]({relative_path(path, base)})" if path.is_file() else text


def notebook_link(run_folder: Path, base: Path, text: str, notebooks: dict | None = None) -> str:
    """Link to a run's executed notebook, or with ``notebooks`` (a published report) to its committed one."""
    if notebooks is None:
        return _link(run_folder / "executed.html", base, text)
    nb = notebooks.get(Path(run_folder).name)
    return _link(nb, base, text) if nb is not None else text
