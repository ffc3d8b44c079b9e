"""Every code block of README.md and docs/*.md, run or checked as a reader would use it.

- ```python blocks run as written, each in a fresh folder (a subprocess, this checkout first on the
  path) holding what the page has made by then: `examples/` for the README, and for docs/output.md a
  run of the paper's scene `shot.h5` (with its `shot.xmf`). The README's block runs twice: in an empty
  folder, and where an interrupted sweep left `sweep.h5.partial/`, so its resume line runs too.
  docs/output.md's SWMR recipe reads a `shot.h5.partial` that is a copy of the finished run (its loop
  ends at once; a reader of a live writer is tests/test_faults.py's).
- ```sh and ```bash blocks: every `warp-ricochet` line is parsed by the command's own parser
  (optional `[--flag]`s as given), every `python FILE` / `python -m MODULE` names a file of the
  checkout and every `make TARGET` a target of the Makefile; the README's Command line block then
  runs in order, but for the lines in NOT_RUN.
- ```toml blocks (scene fragments) are laid over examples/paper.toml and must load.
- ```text blocks are output shown, not input: nothing to run.

Exempt from running (each still parsed or named here): PYTHON_EXEMPT and NOT_RUN below, with the reason.
A block of another language fails `test_every_block_is_of_a_kind_this_file_checks` until it is decided.
"""

import os
import re
import shlex
import shutil
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import pytest

from warp_ricochet.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
PAGES = ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))]
BLOCK = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.S | re.M)
KINDS = {"python", "sh", "bash", "toml", "text"}

# (page, a line of the block) -> why it is not run
PYTHON_EXEMPT = {
    ("docs/output.md", "from paraview.simple import *"): "needs ParaView's pvpython (not on PyPI); tests/test_xdmf.py "
    "reads the same sidecar with VTK's vtkXdmfReader",
    ("docs/output.md", "from MDAnalysis.coordinates.H5MD import H5MDReader"): "needs MDAnalysis (not a test "
    "dependency) and a run with trajectory "
    "frames; tests/test_h5md.py checks the H5MD "
    "elements its reader uses",
}
# README Command line lines parsed but not run (a part of the line) -> why
NOT_RUN = {
    "--device cuda:0": "1e8 pellets on a GPU",
    "--resume": "needs an interrupted run or sweep (tests/test_faults.py, tests/test_sweeps.py resume them)",
}


def blocks(page):
    """[(language, text, line number)] of the fenced blocks of `page`."""
    text = (ROOT / page).read_text()
    return [(m.group(1), m.group(2), text.count("\n", 0, m.start()) + 1) for m in BLOCK.finditer(text)]


def of_kind(*kinds):
    return [pytest.param(page, text, id=f"{page}:{line}") for page in PAGES for lang, text, line in blocks(page) if lang in kinds]


def commands(text):
    """The command lines of a shell block: continuations joined, comments and blank lines dropped."""
    out = []
    for line in text.replace("\\\n", " ").splitlines():
        line = line.split(" #", 1)[0].strip()
        if line and not line.startswith("#"):
            out.append(line)
    return out


def argv_of(line):
    """A `warp-ricochet ...` line as argv, the README's optional `[--flag value]` given."""
    return shlex.split(re.sub(r"\s\[(--[^\]]*)\]", r" \1", line))[1:]


def test_every_block_is_of_a_kind_this_file_checks():
    found = {(page, lang or "(none)") for page in PAGES for lang, _, _ in blocks(page)}
    assert {lang for _, lang in found} <= KINDS, sorted(found)
    assert len(of_kind("python")) >= 10 and len(of_kind("sh", "bash")) >= 3  # the pages' blocks were found
    exempt_found = {key for key in PYTHON_EXEMPT for _, text, _ in blocks(key[0]) if key[1] in text}
    assert exempt_found == set(PYTHON_EXEMPT)  # no stale exemption


# ---------------------------------------------------------------------------------------------- python


@pytest.fixture(scope="module")
def run_files(tmp_path_factory):
    """What docs/output.md reads: a finished run of the paper's scene (every default field), shot.h5."""
    d = tmp_path_factory.mktemp("docs-run")
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "warp_ricochet.cli",
            "run",
            str(ROOT / "examples" / "paper.toml"),
            "--device",
            "cpu",
            "-o",
            "shot.h5",
        ],
        cwd=d,
        capture_output=True,
        text=True,
        timeout=300,
        env=_env(),
    )
    assert proc.returncode == 0, proc.stderr
    return d


def _env():
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]), "MPLBACKEND": "Agg"}


def run_python(text, folder):
    script = folder / "block.py"
    script.write_text(text)
    proc = subprocess.run([sys.executable, script.name], cwd=folder, capture_output=True, text=True, timeout=600, env=_env())
    assert proc.returncode == 0, f"{proc.stdout}\n{proc.stderr}"
    assert "Traceback" not in proc.stderr and "Warning" not in proc.stderr, proc.stderr
    return proc


def _exemption(page, text):
    return next((why for (p, line), why in PYTHON_EXEMPT.items() if p == page and line in text), None)


@pytest.mark.parametrize("page, text", of_kind("python"))
def test_python_block_runs_as_written(page, text, tmp_path, request):
    why = _exemption(page, text)
    if why:
        pytest.skip(why)
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    if page != "README.md":
        made = request.getfixturevalue("run_files")
        for name in ("shot.h5", "shot.xmf"):
            shutil.copy(made / name, tmp_path / name)
        shutil.copy(made / "shot.h5", tmp_path / "shot.h5.partial")  # the SWMR recipe's file: finished, so its loop ends
    run_python(text, tmp_path)


def test_the_readmes_python_block_resumes_an_interrupted_sweep(tmp_path):
    """The block's `resume=True` branch, where its precondition holds: the same sweep interrupted
    after its first point (Ctrl-C in the progress callback) left sweep.h5.partial/."""
    text = next(t for lang, t, _ in blocks("README.md") if lang == "python")
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    interrupt = (
        "import warp_ricochet as wr\n"
        "scene = wr.load_scene('examples/paper.toml')\n"
        "def stop(done, total):\n"
        "    if done > total // 2:\n"
        "        raise KeyboardInterrupt\n"
        "try:\n"
        "    wr.sweep(scene, {'surfaces.0.mu_s': [0.0, 0.05, 0.5]}, [('surfaces.0.mu_d', 0.9, None)], "
        "'sweep.h5', progress=stop)\n"
        "except KeyboardInterrupt:\n"
        "    pass\n"
    )
    run_python(interrupt, tmp_path)
    assert (tmp_path / "sweep.h5.partial" / "0000.h5").exists() and not (tmp_path / "sweep.h5").exists()
    run_python(text, tmp_path)
    assert (tmp_path / "sweep.h5").exists() and not (tmp_path / "sweep.h5.partial").exists()


# ---------------------------------------------------------------------------------------------- shell


def make_targets():
    return set(re.findall(r"^([\w.-]+):", (ROOT / "Makefile").read_text(), re.M))


@pytest.mark.parametrize("page, text", of_kind("sh", "bash"))
def test_shell_block_commands_parse(page, text):
    parser = build_parser()
    for line in commands(text):
        words = shlex.split(line)
        if words[0] == "warp-ricochet":
            argv = argv_of(line)
            try:
                parser.parse_args(argv)
            except SystemExit as exc:  # --version and --help exit 0 by design
                assert exc.code == 0 and argv[0].startswith("--"), (page, line)
        elif words[0] == "python" and words[1] == "-m":
            module = words[2].replace(".", "/")
            assert (ROOT / f"{module}.py").exists() or (ROOT / module / "__main__.py").exists(), (page, line)
        elif words[0] == "python":
            assert (ROOT / words[1]).is_file(), (page, line)
        elif words[0] == "make":
            assert set(words[1:]) <= make_targets(), (page, line)
        else:
            pytest.fail(f"{page}: a command this test does not know how to check: {line}")


def test_the_readmes_command_line_block_runs(tmp_path, monkeypatch, capsys):
    """The README's Command line block in order in an empty folder (with `examples/`), each line
    through `cli.main` as the console script calls it: exit status 0 and what it says it writes."""
    from warp_ricochet.cli import main

    text = next(t for _, t, line in (b for b in blocks("README.md") if b[0] == "sh") if "warp-ricochet run" in t)
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    monkeypatch.chdir(tmp_path)
    ran = 0
    for line in commands(text):
        if any(part in line for part in NOT_RUN):
            continue
        try:
            status = main(argv_of(line))
        except SystemExit as exc:  # --version
            status = exc.code
        assert status == 0, (line, capsys.readouterr().err)
        ran += 1
    out = capsys.readouterr().out
    assert ran >= 10 and "warp-ricochet " in out and "Warp " in out
    for name in (
        "shot.h5",
        "shot.xmf",
        "shot.html",
        "sweep.h5",
        "sweep-air.h5",
        "my-scene.toml",
        "plots/shot-range.png",
        "plots/sweep+sweep-air-sweep-ranges.png",
    ):
        assert (tmp_path / name).exists(), name


# ---------------------------------------------------------------------------------------------- toml


@pytest.mark.parametrize("page, text", of_kind("toml"))
def test_toml_block_is_a_scene_fragment_that_loads(page, text):
    from warp_ricochet.scene import scene_from_dict

    fragment = tomllib.loads(text)  # valid TOML as written
    scene = tomllib.loads((ROOT / "examples" / "paper.toml").read_text())
    for table, values in fragment.items():  # its tables laid over the paper's scene
        scene.setdefault(table, {}).update(values)
    scene_from_dict(scene)  # every key known, every value allowed


# indented (4-space) examples of a surface, the pages' other way to show one: `[[surfaces]]` and its keys
SURFACE_EXAMPLE = re.compile(r"^    \[\[surfaces\]\]\n(?:    .*\n)+", re.M)


def surface_examples():
    return [
        pytest.param(page, m.group(0), id=f"{page}:{text.count(chr(10), 0, m.start()) + 1}")
        for page in PAGES
        for text in [(ROOT / page).read_text()]
        for m in SURFACE_EXAMPLE.finditer(text)
    ]


@pytest.mark.parametrize("page, text", surface_examples())
def test_an_indented_surface_example_is_a_surface_that_loads(page, text):
    """Added to the paper's scene, an example surface loads (one reading a file is only parsed: its
    file, berm.stl or a raster, is the reader's)."""
    from warp_ricochet.scene import scene_from_dict

    (surface,) = tomllib.loads(textwrap.dedent(text))["surfaces"]  # valid TOML as written
    if "file" in surface:
        return
    scene = tomllib.loads((ROOT / "examples" / "paper.toml").read_text())
    scene["surfaces"].append(surface)
    scene_from_dict(scene)  # every key known, every value allowed
