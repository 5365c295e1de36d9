"""Every fenced command of the README and of the docs' guide runs, in the order a reader meets it.

Each ``bash`` line and each ``python`` block of ``README.md`` and ``docs/guide/*.md`` has an entry
in :data:`STAND_INS`; a new command without one fails :func:`test_every_fenced_command_has_a_stand_in`.
Commands run as written where that is cheap; otherwise a stated cheaper stand-in runs the same
code path:

* ``make X`` runs ``make -n -B X`` (the recipe as make would run it) and then the recipe's own
  ``prodmaps`` command at smoke scale into a temporary folder (``make test`` is this suite; the
  docs build is ``tests/docs/test_docs.py``; ``make bench`` is ``tests/benchmarks``);
* ``prodmaps reproduce`` runs with ``--profile smoke`` (the paper profile takes minutes) and
  ``--out`` a temporary folder; "everything" is two runs (``fig02 fig03``) in the same pool;
* the FAUST preparation runs as written on two folders holding fake registrations (FAUST's real
  counts), the FAUST reproduction is checked against the registry and refused cleanly when FAUST
  is not prepared (this machine's data root is replaced by an empty one);
* ``git clone`` of the remeshed collections writes a fake clone in their layout instead (every
  shape id, ~5000-vertex spheres, 5000 or 900 samples, no ``maps/``); their preparations run as
  written on it (a second documented run is refused: the dataset exists), and the cross-dataset
  snippet runs on them with a fake ``tr_reg_000`` registration added;
* the pyFM snippets run on stand-ins of pyFM's ``TriMesh`` and ``FunctionalMapping`` (the real
  pyFM is exercised in ``tests/crosscheck``).

Every stand-in asserts on what the command must do (exit status, files written, numbers or the
message of a refusal), and no command may change a tracked file: ``git status`` is compared before
and after.
"""

from __future__ import annotations

import hashlib
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SOURCES = [ROOT / "README.md", *sorted((ROOT / "docs" / "guide").glob("*.md"))]


def fenced_blocks(path: Path) -> list[tuple[str, str, int]]:
    """``(language, text, first line)`` of every fenced block of a Markdown file."""
    out, lang, buf, start = [], None, [], 0
    for i, line in enumerate(path.read_text().splitlines(), 1):
        m = re.match(r"^```(\S*)\s*$", line)
        if m and lang is None:
            lang, buf, start = m.group(1) or "text", [], i + 1
        elif line.startswith("```") and lang is not None:
            out.append((lang, "\n".join(buf), start))
            lang = None
        elif lang is not None:
            buf.append(line)
    return out


def bash_commands(text: str) -> list[str]:
    """The commands of a bash block: continuations joined, comments and blank lines dropped."""
    text = text.replace("\\\n", " ")
    cmds = []
    for line in text.splitlines():
        line = re.sub(r"\s+#.*$", "", line).strip()
        if line and not line.startswith("#"):
            cmds.append(" ".join(line.split()))
    return cmds


def documented() -> list[tuple[str, str, str]]:
    """``(where, kind, command or python block)`` in reading order."""
    out = []
    for path in SOURCES:
        for lang, text, line in fenced_blocks(path):
            where = f"{path.relative_to(ROOT)}:{line}"
            if lang == "bash":
                out += [(where, "bash", c) for c in bash_commands(text)]
            elif lang == "python":
                out.append((where, "python", text))
    return out


def _python_key(text: str) -> str:
    """A python block's stand-in key: its first statement that is not an import."""
    for line in text.splitlines():
        s = line.strip()
        if s and not s.startswith(("import ", "from ", "#")):
            return "python: " + s.split("#")[0].strip()
    return "python: " + text.strip().splitlines()[0]


# command (or python block key) -> stand-in name; every entry must be documented somewhere
STAND_INS = {
    "make reproduce": "make_reproduce",
    "make test": "make_dry_run",
    "make publish": "make_publish",
    "make venv": "make_dry_run",
    "make docs": "make_dry_run",
    "pip install .": "pip_install",
    "python -m prodmaps.prepare faust --archive FundCG-s1-2018 --archive Laplacian-Mesh": "prepare_faust",
    "prodmaps reproduce --dataset faust --only tab01 tab02 tab03 tab04 tab06 fig08 fig11 fig12_13 fig14 "
    "study_normalization study_no17 study_default study_family_readings": "reproduce_faust",
    ".venv/bin/prodmaps reproduce --only fig03 --profile paper -p 'k_values=[4,8,12,16]'": "reproduce_override",
    ".venv/bin/prodmaps reproduce --profile smoke --jobs 2": "reproduce_smoke",
    ".venv/bin/prodmaps diff results/smoke/fig03 paper/baselines/smoke/fig03": "diff",
    ".venv/bin/prodmaps claims results/paper": "claims",
    'python: m1 = pm.datasets.load_shape("anny_humans", "anny_000")': "python_as_written",
    "python: b1 = pm.basis.from_arrays(mesh1.eigenvectors[:, :k1], mesh1.eigenvalues[:k1], mesh1.vertex_areas)":
        "python_pyfm",
    'python: mesh = pm.load_mesh("scan.ply")': "python_scan",
    'python: cloud = pm.load_point_cloud("scan.xyz")': "python_cloud",
    'python: camel = pm.load_mesh("camel-gallop-01.off", validate=False)': "python_camel",
    "git clone https://github.com/llorz/SGA18_orientation_BCICP_dataset": "sga18_clone",
    "python -m prodmaps.prepare faust_r --archive SGA18_orientation_BCICP_dataset": "prepare_sga18",
    "python -m prodmaps.prepare tosca_r --archive SGA18_orientation_BCICP_dataset": "prepare_sga18",
    "python -m prodmaps.prepare tosca_r_noniso --archive SGA18_orientation_BCICP_dataset": "prepare_sga18",
    'python: p2p_21 = pm.datasets.ground_truth_between(("faust", "tr_reg_000"), ("faust_r", "tr_reg_000"))':
        "python_cross",
    "python: class DampedTransfer(TransferOperator):": "python_new_method",
}


def _key(kind: str, text: str) -> str:
    return text if kind == "bash" else _python_key(text)


def test_every_fenced_command_has_a_stand_in():
    keys = [_key(kind, text) for _, kind, text in documented()]
    missing = [f"{w}: {_key(k, t)}" for w, k, t in documented() if _key(k, t) not in STAND_INS]
    assert not missing, "documented commands without a stand-in in this test:\n" + "\n".join(missing)
    stale = sorted(set(STAND_INS) - set(keys))
    assert not stale, f"stand-ins of commands no longer documented: {stale}"


def test_fenced_block_reader_joins_continuations_and_drops_comments():
    cmds = bash_commands("make a   # one\n# only a comment\nprodmaps x --only a \\\n    b   # two\n\n")
    assert cmds == ["make a", "prodmaps x --only a b"]


# ------------------------------------------------------------------------------- the stand-ins

def _tracked_state() -> str:
    """``git status`` of tracked files plus a hash of the committed report (what must not change)."""
    st = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                        capture_output=True, text=True).stdout
    report = ROOT / "paper" / "REPORT.md"
    return st + hashlib.sha256(report.read_bytes()).hexdigest()


class Reader:
    """Runs the documented commands' stand-ins with one temporary results folder and data root."""

    def __init__(self, tmp: Path):
        self.tmp = tmp
        self.out = tmp / "results"
        self.env = dict(os.environ, PRODMAPS_DATA=str(tmp / "data"), PRODMAPS_WORKERS="1")
        self.done: dict[str, subprocess.CompletedProcess] = {}

    def run(self, argv, cwd=ROOT, check=True, timeout=900):
        p = subprocess.run(argv, cwd=cwd, env=self.env, capture_output=True, text=True, timeout=timeout)
        if check:
            assert p.returncode == 0, f"{shlex.join(map(str, argv))} failed:\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}"
        return p

    def prodmaps(self, args: list[str], **kw):
        return self.run([sys.executable, "-m", "prodmaps", *args], **kw)

    def cli_args(self, cmd: str) -> list[str]:
        """The arguments after ``prodmaps`` with the README's folders mapped into the temporary one."""
        argv = shlex.split(cmd)
        assert Path(argv[0]).name == "prodmaps", argv
        args = argv[1:]
        mapped = []
        for a in args:
            if a.startswith("results/paper"):  # the claims example reads the paper run: the smoke one here
                a = str(self.out / "smoke") + a[len("results/paper"):]
            elif a.startswith("results/"):
                a = str(self.out / a[len("results/"):])
            mapped.append(a)
        return mapped

    def make_recipe(self, target: str) -> str:
        # -B: the whole recipe, also when its targets are up to date (a fresh venv has nothing to do)
        venv = Path(sys.executable).parents[1]
        p = self.run(["make", "-n", "-B", target, f"PYTHON={sys.executable}", f"VENV={venv}"])
        return p.stdout


@pytest.fixture(scope="module")
def reader(tmp_path_factory):
    before = _tracked_state()
    r = Reader(tmp_path_factory.mktemp("reader"))
    yield r
    assert _tracked_state() == before, "a documented command changed a tracked file"


def _prodmaps_line(recipe: str, sub: str) -> list[str]:
    for line in recipe.splitlines():
        if f"-m prodmaps {sub}" in line:
            return shlex.split(line.split("-m prodmaps", 1)[1])
    raise AssertionError(f"no `prodmaps {sub}` in the recipe:\n{recipe}")


def stand_in_make_reproduce(r: Reader, cmd: str):
    args = _prodmaps_line(r.make_recipe("reproduce"), "reproduce")
    assert args[0] == "reproduce" and "--profile" in args and "--out" in args
    args[args.index("--profile") + 1] = "smoke"      # stand-in: the smoke profile, one run
    args[args.index("--out") + 1] = str(r.out)
    r.prodmaps([*args, "--only", "fig02", "--no-progress"])
    assert (r.out / "smoke" / "fig02" / "results.json").is_file()
    assert (r.out / "smoke" / "REPORT.md").is_file()  # the report beside the results, paper/ untouched


def stand_in_make_publish(r: Reader, cmd: str):
    args = _prodmaps_line(r.make_recipe("publish"), "publish")
    assert args[0] == "publish"
    p = r.prodmaps(["publish", str(r.out / "smoke")], check=False)  # a partial smoke run: refused
    assert p.returncode != 0
    assert re.search(r"partial|smoke|profile", p.stdout + p.stderr, re.I), p.stdout + p.stderr


def stand_in_make_dry_run(r: Reader, cmd: str):
    target = cmd.split()[1]
    recipe = r.make_recipe(target)
    expected = {"test": "pytest", "venv": "pip", "docs": "sphinx"}[target]
    assert expected in recipe, recipe


def stand_in_pip_install(r: Reader, cmd: str):
    # stand-in: build the package's metadata (in pip's isolated build environment) without
    # installing (tests/docs/test_packaging.py checks the ranges; a real install takes a minute)
    p = r.run([sys.executable, "-m", "pip", "install", "--dry-run", "--no-deps", "."], timeout=300)
    assert "Would install prodmaps" in p.stdout, p.stdout


def stand_in_prepare_faust(r: Reader, cmd: str):
    from scipy.spatial import ConvexHull

    i = np.arange(6890) + 0.5  # FAUST's counts: the convex hull of 6890 sphere points has 13776 faces
    phi, th = np.arccos(1 - 2 * i / 6890), np.pi * (1 + 5**0.5) * i
    v = np.column_stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)])
    f = ConvexHull(v).simplices
    work = r.tmp / "clones"
    for repo, sid in (("FundCG-s1-2018", 2), ("Laplacian-Mesh", 5)):  # the registrations lie deeper
        (work / repo / "data").mkdir(parents=True)
        rows = [f"{x:.9f} {y:.9f} {z:.9f}" for x, y, z in v * (1 + sid / 10)] + [f"3 {a} {b} {c}" for a, b, c in f]
        off = f"OFF\n{len(v)} {len(f)} 0\n" + "\n".join(rows) + "\n"
        (work / repo / "data" / f"tr_reg_{sid:03d}.off").write_text(off)
    argv = shlex.split(cmd)
    assert argv[:3] == ["python", "-m", "prodmaps.prepare"]
    p = r.run([sys.executable, *argv[1:]], cwd=work)
    assert "found 2 of the 100 registrations" in p.stdout, p.stdout
    assert (r.tmp / "data" / "faust" / "manifest.json").is_file()


def _fib_sphere(n: int, phase: float = 0.0):
    from scipy.spatial import ConvexHull

    i = np.arange(n) + 0.5
    phi, th = np.arccos(1 - 2 * i / n), np.pi * (1 + 5**0.5) * i + phase
    v = np.column_stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)])
    return v, ConvexHull(v).simplices


def _off(v, f) -> str:
    rows = [f"{x:.7f} {y:.7f} {z:.7f}" for x, y, z in v] + [f"3 {a} {b} {c}" for a, b, c in f]
    return f"OFF\n{len(v)} {len(f)} 0\n" + "\n".join(rows) + "\n"


def stand_in_sga18_clone(r: Reader, cmd: str):
    from scipy.spatial import cKDTree

    from prodmaps.prepare.sga18 import COLLECTIONS

    clone = r.tmp / "clones" / cmd.split("/")[-1]
    if clone.is_dir():  # documented twice: cloned once
        return
    tpl, _ = _fib_sphere(6890)  # the FAUST template (faust_r's sampleID indexes it)
    sample_tpl = np.random.default_rng(0).choice(6890, size=5000, replace=False)
    meshes = [_fib_sphere(4990 + 3 * k, phase=0.1 * k) for k in range(3)]  # three triangulations, cycled
    for name, coll in COLLECTIONS.items():
        vtx = clone / "Dataset" / coll.folder / "vtx_5k"
        (vtx / "corres").mkdir(parents=True)
        dirs = tpl[sample_tpl[:coll.n_samples]]
        for k, sid in enumerate(coll.ids):
            v, f = meshes[k % 3]
            (vtx / f"{sid}.off").write_text(_off(v * (1 + (k % 7) / 10), f))
            s = cKDTree(v).query(dirs)[1] + 1
            (vtx / "corres" / f"{sid}.vts").write_text("\n".join(map(str, s)) + "\n")
        for g in {coll.group_of(sid) for sid in coll.ids}:
            if coll.template_file(g):
                (vtx / "corres" / coll.template_file(g)).write_text(
                    "\n".join(map(str, sample_tpl[:coll.n_samples] + 1)) + "\n")
        (vtx.parent / "test_pairs.txt").write_text(f"{coll.ids[0]}\t{coll.ids[1]}\n")
    (clone / "README.md").write_text("# Datasets\n")


def stand_in_prepare_sga18(r: Reader, cmd: str):
    import json

    argv = shlex.split(cmd)
    assert argv[:3] == ["python", "-m", "prodmaps.prepare"]
    name, target = argv[3], r.tmp / "data" / argv[3]
    existed = target.is_dir()
    p = r.run([sys.executable, *argv[1:]], cwd=r.tmp / "clones", check=not existed)
    if existed:  # the same command documented twice: the second run is refused, the dataset untouched
        assert p.returncode == 2 and "already exists; pass --force" in p.stderr, p.stderr
        return
    n = {"faust_r": 100, "tosca_r": 76, "tosca_r_noniso": 24}[name]
    assert f"wrote {n} shapes to {target}" in p.stdout, p.stdout
    man = json.loads((target / "manifest.json").read_text())
    assert len(man["shapes"]) == n and man["ground_truth"]["kind"] == "samples"


def stand_in_python_cross(r: Reader, text: str):
    import prodmaps as pm

    v, f = _fib_sphere(6890)  # a fake registration tr_reg_000 beside the fake faust_r
    (r.tmp / "reg000").mkdir(exist_ok=True)
    (r.tmp / "reg000" / "tr_reg_000.off").write_text(_off(v, f))
    r.run([sys.executable, "-m", "prodmaps.prepare", "faust", "--archive", str(r.tmp / "reg000"), "--force"])
    old = os.environ.get("PRODMAPS_DATA")
    os.environ["PRODMAPS_DATA"] = r.env["PRODMAPS_DATA"]
    pm.datasets.clear_cache()
    try:
        ns: dict = {}
        _exec(text, ns, r.tmp)
        rem = pm.datasets.load_shape("faust_r", "tr_reg_000")
        tpl = np.loadtxt(r.tmp / "data" / "faust_r" / "samples" / "faust.template.txt", dtype=int)
        s = pm.datasets.sample_vertices("faust_r", "tr_reg_000")
        assert ns["p2p_21"].shape == (rem.n_vertices,) and ns["p2p_21"][s[0]] == tpl[0]
    finally:
        if old is None:
            os.environ.pop("PRODMAPS_DATA")
        else:
            os.environ["PRODMAPS_DATA"] = old
        pm.datasets.clear_cache()


def stand_in_reproduce_faust(r: Reader, cmd: str):
    from prodmaps.pipeline import registry

    args = r.cli_args(cmd)
    runs = args[args.index("--only") + 1:]
    assert set(runs) <= set(registry.load_registry(ROOT / "paper" / "runs.toml")), runs
    # FAUST prepared (above): every named run is listed; with an empty data root: refused before running
    listed = r.prodmaps([*args, "--list"]).stdout
    assert all(name in listed for name in runs), listed
    empty = dict(r.env, PRODMAPS_DATA=str(r.tmp / "no-data"))
    p = subprocess.run([sys.executable, "-m", "prodmaps", *args, "--out", str(r.out)], cwd=ROOT, env=empty,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode != 0 and re.search(r"faust.*prepare|prepare.*faust", p.stdout + p.stderr, re.I | re.S)
    assert not (r.out / "paper-faust").exists()


def stand_in_reproduce_override(r: Reader, cmd: str):
    args = r.cli_args(cmd)
    args[args.index("--profile") + 1] = "smoke"
    r.prodmaps([*args, "--out", str(r.out), "--no-progress"])
    res = (r.out / "smoke" / "fig03" / "results.json").read_text()
    assert re.search(r"4,\s*8,\s*12,\s*16", res), "the overridden k_values are not in the results"
    assert "k_values" in (r.out / "smoke" / "REPORT.md").read_text()  # the override is shown


def stand_in_reproduce_smoke(r: Reader, cmd: str):
    args = r.cli_args(cmd)
    r.prodmaps([*args, "--out", str(r.out), "--only", "fig02", "fig03", "--no-progress"])
    for run in ("fig02", "fig03"):
        assert (r.out / "smoke" / run / "executed.ipynb").is_file()


def stand_in_diff(r: Reader, cmd: str):
    p = r.prodmaps(r.cli_args(cmd))
    assert re.search(r"\b[1-9]\d* values compared, 0 drifted; [1-9]\d* images compared, 0 drifted", p.stdout), p.stdout


def stand_in_claims(r: Reader, cmd: str):
    p = r.prodmaps(r.cli_args(cmd))
    assert "holds" in p.stdout or "not measured" in p.stdout, p.stdout


def _exec(text: str, ns: dict, cwd: Path):
    old = os.getcwd()
    os.chdir(cwd)
    try:
        exec(compile(text, "<fenced block>", "exec"), ns)
    finally:
        os.chdir(old)


def stand_in_python_as_written(r: Reader, text: str):
    ns: dict = {}
    _exec(text, ns, r.tmp)
    import prodmaps as pm

    # the snippets' claim: the default extended transfer beats the standard one on the coordinates
    f, p2p_21, b2 = ns["f"], ns["p2p_21"], ns["b2"]
    err_ext = pm.relative_error(ns["g_ext"], f[p2p_21], b2.mass)  # (3,): one per coordinate
    assert np.all(err_ext < pm.relative_error(ns["g_std"], f[p2p_21], b2.mass)), err_ext


def _pyfm_stand_ins():
    import prodmaps as pm

    m1 = pm.datasets.load_shape("anny_humans", "anny_000")
    m2 = pm.datasets.load_shape("anny_humans", "anny_013")
    b1, b2 = pm.eigenbasis(m1, 12), pm.eigenbasis(m2, 30)

    def trimesh(b):  # pyFM's TriMesh: eigenvectors (n, K), eigenvalues (K,), vertex_areas (n,)
        return SimpleNamespace(eigenvectors=b.vecs, eigenvalues=b.evals, vertex_areas=b.mass)

    C = pm.fmap_from_p2p(np.arange(m2.n_vertices), b1, b2)
    return dict(mesh1=trimesh(b1), mesh2=trimesh(b2), k1=10, k2=30, f=m1.vertices,
                model=SimpleNamespace(FM_12=C[:, :10]))


def stand_in_python_pyfm(r: Reader, text: str):
    ns = _pyfm_stand_ins()
    _exec("import prodmaps as pm\n" + text, ns, r.tmp)
    assert ns["g"].shape == ns["f"].shape
    assert ns["b1"].k == 10 and ns["b2"].k == 30


def stand_in_python_scan(r: Reader, text: str):
    import prodmaps as pm

    shutil.copy(pm.datasets.dataset_dir("anny_humans") / "shapes" / "anny_000.ply", r.tmp / "scan.ply")
    human = pm.datasets.load_shape("anny_humans", "anny_000")
    np.savetxt(r.tmp / "scan.xyz", human.vertices[::2])  # a cloud: every other vertex
    ns: dict = {}
    _exec(text, ns, r.tmp)
    assert ns["mesh"].n_vertices == human.n_vertices
    assert ns["cloud"].n_points == (human.n_vertices + 1) // 2 and ns["cloud"].normals is None


def stand_in_python_cloud(r: Reader, text: str):
    """The guide's point-cloud block on an ellipsoid and the cloud of every other vertex (truth: 2 i)."""
    import prodmaps as pm

    mesh = pm.mesh.ellipsoid(3)
    np.savetxt(r.tmp / "scan.xyz", mesh.vertices[::2])
    B1 = pm.eigenbasis(mesh, 30)
    B2 = pm.eigenbasis(pm.PointCloud(mesh.vertices[::2]), 30)
    lm = [[2 * i, i] for i in (0, 50, 100, 150, 200)]
    d_mesh, d_cloud = pm.fmaps.no17_demo_descriptors(B1, B2, lm)
    ns = dict(mesh=mesh, d_mesh=d_mesh, d_cloud=d_cloud, f=mesh.vertices)
    _exec("import prodmaps as pm\n" + text, ns, r.tmp)
    assert ns["C_12"].shape == (10, 10) and ns["g"].shape == (321, 3)
    assert np.mean(ns["p2p_21"] == 2 * np.arange(321)) > 0.8  # the point map finds the sampled vertices ...
    dist = np.linalg.norm(mesh.vertices[ns["p2p_21"]] - mesh.vertices[::2], axis=1)
    assert dist.mean() < 0.02  # ... or one of their neighbours (the ellipsoid is 2 long)


def stand_in_python_camel(r: Reader, text: str):
    """The guide's camel block on a stand-in with pyFM's camel's defects: a duplicated face, a non-manifold edge."""
    import prodmaps as pm

    e = pm.mesh.ellipsoid(2)
    a, b, _ = e.faces[10]
    V = np.vstack([e.vertices, 0.525 * (e.vertices[a] + e.vertices[b])])
    F = np.vstack([e.faces, e.faces[5][::-1], [[a, b, e.n_vertices]]])
    pm.save_mesh(r.tmp / "camel-gallop-01.off", V, F)
    with pytest.raises(pm.MeshError, match="kind='robust'"):
        pm.io.load_mesh_repaired(r.tmp / "camel-gallop-01.off", verbose=False)
    ns: dict = {}
    _exec("import prodmaps as pm\n" + text, ns, r.tmp)
    assert ns["basis"].kind == "robust" and ns["basis"].vecs.shape == (163, 50)


def stand_in_python_new_method(r: Reader, text: str):
    """The developer guide's worked example registers a method that every transfer then offers."""
    import prodmaps as pm
    from prodmaps.transfers import REGISTRY

    ns: dict = {}
    try:
        _exec(text, ns, r.tmp)
        assert REGISTRY["damped"].parameters == {"damping": 1e-3}
        mesh = pm.mesh.ellipsoid(2)
        b = pm.eigenbasis(mesh, 6)
        C = pm.fmap_from_p2p(np.arange(b.n), b, b)
        f = mesh.vertices[:, 0] * mesh.vertices[:, 1]
        g = pm.transfer(f, C, b, b, "damped", damping=1e-2)
        np.testing.assert_array_equal(g, pm.transfer(f, C, b, b, "ridge", eps=1e-4))  # eps = damping²
        with pytest.raises(TypeError, match="takes no parameter 'rtol'"):
            pm.transfer(f, C, b, b, "damped", rtol=1e-3)
    finally:
        REGISTRY.pop("damped", None)


@pytest.mark.parametrize("where, kind, text", documented(), ids=[f"{w}" for w, _, _ in documented()])
def test_documented_command_runs(reader, where, kind, text):
    name = STAND_INS.get(_key(kind, text))
    assert name is not None, f"{where}: no stand-in for {_key(kind, text)!r}"
    globals()[f"stand_in_{name}"](reader, text)
