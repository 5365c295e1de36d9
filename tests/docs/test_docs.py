"""The documentation site: `make docs` builds with warnings as errors; its gallery and report pages.

The build runs once (about 25 s) into a temporary folder, exactly as ``make docs`` runs it.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

import prodmaps as pm
from prodmaps.pipeline import gallery
from prodmaps.pipeline.registry import load_registry

ROOT = Path(__file__).resolve().parents[2]
BASELINES = ROOT / "paper" / "baselines" / "smoke"


def sphinx_build(out: Path, runs=None) -> subprocess.CompletedProcess:
    env = dict(os.environ, PRODMAPS_DOCS_RUNS=str(runs or ""))
    return subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                           str(ROOT / "docs"), str(out)], capture_output=True, text=True, timeout=900,
                          cwd=ROOT, env=env)


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    pytest.importorskip("sphinx")  # part of prodmaps[docs], installed by `make venv` / `make test`
    out = tmp_path_factory.mktemp("site")
    r = sphinx_build(out)
    assert r.returncode == 0, r.stdout + r.stderr
    return out, r


def test_docs_build_has_no_warnings(site):
    _, r = site
    assert "WARNING" not in r.stderr and "ERROR" not in r.stderr, r.stderr


def test_front_page_guide_and_api(site):
    out, _ = site
    front = (out / "index.html").read_text()
    for link in ("guide/index.html", "api.html", "_generated/gallery/index.html", "_generated/report.html"):
        assert link in front, link
    for page in ("install", "quickstart", "conventions", "coming_from", "own_meshes", "default_transfer", "point_maps"):
        assert (out / "guide" / f"{page}.html").is_file(), page
    install = re.sub(r"<[^>]+>", "", (out / "guide" / "install.html").read_text())
    assert "pip install ." in install  # the library alone, without the extras
    api = (out / "api.html").read_text()
    for name in pm.__all__:  # every public name documented, with its example
        assert f'id="prodmaps.{name}"' in api, name
    assert api.count("Examples") >= len(pm.__all__)


def test_gallery_has_every_run_with_its_baseline_figures(site):
    out, _ = site
    runs = load_registry()
    for name in runs:
        page = out / "_generated" / "gallery" / f"{name}.html"
        assert page.is_file(), name
        n_png = len(list((BASELINES / name).glob("*.png")))
        n_img = len(re.findall(r"<img[^>]+src=\"[^\"]*\.png\"", page.read_text()))
        assert n_img >= n_png, (name, n_img, n_png)


def test_report_page_links_to_gallery_pages_and_shows_its_figures(site):
    out, _ = site
    page = (out / "_generated" / "report.html").read_text()
    assert "executed.html" not in page  # links lead to the gallery, not to a results folder
    assert re.search(r'href="gallery/tab01.html"', page)
    figures = re.findall(r"<img[^>]+src=\"([^\"]+\.png)\"", page)
    assert figures and all((out / "_generated" / f).is_file() for f in figures)


def test_gallery_uses_executed_notebooks_of_a_run_folder(tmp_path):
    runs = tmp_path / "smoke"
    nb = nbformat.read(ROOT / "notebooks" / "fig02_fourier_products.ipynb", as_version=4)
    png = "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg=="
    code = next(c for c in nb.cells if c.cell_type == "code")
    code.outputs = [nbformat.v4.new_output("display_data", data={"image/png": png, "text/plain": "<Figure>"})]
    (runs / "fig02").mkdir(parents=True)
    nbformat.write(nb, runs / "fig02" / "executed.ipynb")
    names = gallery.write_gallery(tmp_path / "g", runs)
    assert names == list(load_registry())
    shown = nbformat.read(tmp_path / "g" / "fig02.ipynb", as_version=4)
    outputs = [o for c in shown.cells if c.cell_type == "code" for o in c.outputs]
    assert any("image/png" in o.get("data", {}) for o in outputs)  # the executed notebook, figures inline
    other = nbformat.read(tmp_path / "g" / "fig03.ipynb", as_version=4)  # not in the folder: stripped + baselines
    assert not [o for c in other.cells if c.cell_type == "code" for o in c.outputs]
    assert "fig03__fig03_fourier_indicator.png" in other.cells[1].source
    assert (tmp_path / "g" / "fig03__fig03_fourier_indicator.png").is_file()
    titles = [nbformat.read(tmp_path / "g" / f"tab0{i}.ipynb", as_version=4).cells[0].source.splitlines()[0]
              for i in range(1, 7)]  # one notebook, six runs: each page titled by its own run
    assert titles == [f"# Table {i}: {load_registry()[f'tab0{i}'].title}" for i in range(1, 7)]


def test_front_page_screenshot_in_headless_chromium(site, tmp_path):
    browser = next((b for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)
    if browser is None:
        pytest.skip("chromium is not installed (Debian: apt-get install chromium)")
    from PIL import Image

    out, _ = site
    shot = tmp_path / "front.png"
    r = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                        f"--screenshot={shot}", "--window-size=1280,900", (out / "index.html").as_uri()],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and shot.is_file(), r.stderr[-2000:]
    img = Image.open(shot).convert("RGB")
    assert img.size == (1280, 900)
    colours = img.getcolors(maxcolors=1 << 20)
    assert colours is not None and len(colours) > 50  # text and theme drawn, not a blank page
    dark = sum(n for n, (r_, g, b) in colours if r_ + g + b < 200)
    assert dark > 0.002 * 1280 * 900  # some text is drawn


def test_report_page_of_a_published_report_links_gallery_pages(tmp_path):
    """A published report links the committed notebooks (../notebooks/*.ipynb): the site turns them into
    gallery pages and never needs results/."""
    report = tmp_path / "paper" / "REPORT.md"
    (tmp_path / "paper" / "report_figures" / "fig02").mkdir(parents=True)
    png = tmp_path / "paper" / "report_figures" / "fig02" / "a.png"
    shutil.copyfile(next((BASELINES / "fig02").glob("*.png")), png)
    report.write_text("# R\n\n| run | read |\n|---|---|\n| `tab03` | [notebook](../notebooks/tables_transfer.ipynb) |\n"
                      "\n[tab04](../notebooks/tables_transfer.ipynb), [x](../notebooks/fig02_fourier_products.ipynb)\n"
                      "\n![fig02 a](report_figures/fig02/a.png)\n", encoding="utf-8")
    names = list(load_registry())
    page = gallery.write_report_page(tmp_path / "site", report, names).read_text(encoding="utf-8")
    assert "(gallery/tab01.ipynb)" in page and "[tab04](gallery/tab04.ipynb)" in page
    assert "[x](gallery/fig02.ipynb)" in page and "../notebooks" not in page
    assert (tmp_path / "site" / "report_figures" / "fig02" / "a.png").is_file()


def test_docs_runs_is_resolved_from_the_project_root(tmp_path):
    """`make docs DOCS_RUNS=results/smoke` names the folder from the project root (conf.py lives in docs/)."""
    runs = tmp_path / "smoke"
    nb = nbformat.read(ROOT / "notebooks" / "fig02_fourier_products.ipynb", as_version=4)
    code = next(c for c in nb.cells if c.cell_type == "code")
    code.outputs = [nbformat.v4.new_output("stream", text="EXECUTED-MARKER\n")]
    (runs / "fig02").mkdir(parents=True)
    nbformat.write(nb, runs / "fig02" / "executed.ipynb")
    rel = os.path.relpath(runs, ROOT)  # relative to the project root, as the Makefile passes it
    code = "import runpy; runpy.run_path('conf.py')"
    env = dict(os.environ, PRODMAPS_DOCS_RUNS=rel)
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT / "docs", env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    shown = nbformat.read(ROOT / "docs" / "_generated" / "gallery" / "fig02.ipynb", as_version=4)
    assert any("EXECUTED-MARKER" in o.get("text", "") for c in shown.cells if c.cell_type == "code"
               for o in c.outputs)
    env["PRODMAPS_DOCS_RUNS"] = "results/no_such_folder"  # a typo fails the build instead of showing nothing
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT / "docs", env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode != 0 and "no executed notebooks" in r.stderr


def test_api_reference_has_a_page_per_module_and_one_parameters_block_per_entry(site):
    out, _ = site
    pages = {p.stem for p in (out / "api").glob("*.html")}
    for mod in ("mesh", "io", "basis", "products", "approx", "mapping", "p2p", "neighbors", "fmaps", "descriptors",
                "geodesics", "metrics", "lmh", "fields"):
        assert mod in pages, mod
    wanted = {"p2p": ["prodmaps.p2p.from_fmap", "prodmaps.p2p.fmap_from_p2p"],
              "neighbors": ["prodmaps.neighbors.nearest_neighbors", "prodmaps.neighbors.probe_neighbors"],
              "geodesics": ["prodmaps.geodesics"],
              "mesh": ["prodmaps.mesh.repair", "prodmaps.mesh.remove_unreferenced_vertices",
                       "prodmaps.mesh.remove_degenerate_faces", "prodmaps.mesh.largest_component"],
              "io": ["prodmaps.io.load_mesh_repaired"]}
    for page, ids in wanted.items():
        text = (out / "api" / f"{page}.html").read_text()
        for i in ids:
            assert f'id="{i}' in text, (page, i)
    api = (out / "api.html").read_text()
    for name in ("transfer", "eigenbasis", "product_basis"):  # types come from the docstring, not a second block
        entry = api.split(f'id="prodmaps.{name}"', 1)[1].split('<dl class="py', 1)[0]
        assert entry.count(">Parameters<") == 1, name
