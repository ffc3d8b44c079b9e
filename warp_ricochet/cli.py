"""The `warp-ricochet` command: run a scene, sweep parameters, report Tables 1-3 of Zohdi (2021).

    warp-ricochet run SCENE.toml [-o OUT.h5] [--device cpu|cuda|cuda:N] [--set KEY=VALUE ...] [--overwrite] [--resume]
                      [--units metric|imperial]
    warp-ricochet sweep SCENE.toml --param KEY=START:STOP:STEP|a,b,c [--tie KEY=F*[PARAM] ...] [-o OUT.h5] ...
    warp-ricochet report OUT.h5 [OUT2.h5 ...] [--format text|markdown] [--paper] [--html OUT.html [--overwrite]] [--units ...]
    warp-ricochet xdmf OUT.h5 [--overwrite]
    warp-ricochet plot OUT.h5 [OUT2.h5 ...] [-o DIR] [--overwrite]
    warp-ricochet example [NAME] [-o PATH] [--overwrite]
    warp-ricochet export RUN.h5 [--geojson OUT.geojson] [--geotiff OUT.tif] [--p P ...] [--overwrite]
    warp-ricochet loads
    warp-ricochet --version | [-q|--quiet] [-v|--verbose] COMMAND ...

`--quiet` and `--verbose` (before or after COMMAND) set the level of the package's `logging` loggers
(`warp_ricochet`, and Python warnings through `py.warnings`): warnings by default, errors only with
`--quiet` (no progress bar either), informational lines with `-v` and debugging lines with `-vv`.
Exit status: 0 on success; 2 for a usage error or any invalid scene, override, device, output path or
report input (one line `warp-ricochet: error: ...` on stderr, no traceback); 1 for an operating-system
error such as a full disk; 130 when interrupted. Warp itself is imported only by `run` and `sweep`.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import ctypes
import functools
import logging
import os
import signal
import sys
import threading
import warnings

from . import display, interrupts
from ._version import __version__
from .errors import MAX_MESSAGE, RicochetError, SceneError, shorten

PROG = "warp-ricochet"

EPILOG = """examples:
  warp-ricochet run examples/paper.toml -o run.h5
  warp-ricochet sweep examples/paper.toml --param surfaces.0.mu_s=0:0.5:0.05 --tie surfaces.0.mu_d=0.9* -o sweep.h5
  warp-ricochet report sweep.h5 --paper
  warp-ricochet xdmf run.h5          # run.xmf: open it in ParaView
  warp-ricochet plot sweep.h5 -o plots/
  warp-ricochet example paper -o my-scene.toml
  warp-ricochet export run.h5 --geojson danger.geojson --geotiff map.tif"""


# ---------------------------------------------------------------------------------------------- parser


def _add_scene_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", metavar="SCENE.toml", help="scene file (TOML; see examples/paper.toml)")
    p.add_argument(
        "-o", "--output", metavar="OUT.h5", help="HDF5 file to write (default: the scene's output.path; none: statistics only)"
    )
    p.add_argument("--device", metavar="DEVICE", help="Warp device: cpu, cuda or cuda:N (default: CUDA if present, else cpu)")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scene value, e.g. --set shot.count=1000 --set surfaces.0.mu_s=0.2 (VALUE is a TOML value; repeatable)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace OUT.h5 if it exists")
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--cluster",
        metavar="local:N",
        help="compute on a new Dask cluster of N workers on this machine (one a GPU with a CUDA device); "
        "bitwise the serial result (docs/cluster.md)",
    )
    where.add_argument("--scheduler", metavar="ADDRESS", help="compute on the Dask cluster whose scheduler is at ADDRESS")


def _add_report_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--format",
        choices=("text", "markdown"),
        default="text",
        help="text (aligned columns, default) or markdown (GitHub tables)",
    )
    p.add_argument(
        "--paper",
        action="store_true",
        help="also print the paper's values for the same mu_s and the relative differences of the ranges",
    )


def _add_units(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--units",
        choices=("metric", "imperial"),
        default="metric",
        help="units of the printed summary and tables (and of the HTML report's figures): metric (SI, default) "
        "or imperial (distances in yards, speeds in ft/s; energies stay in J); files are SI either way",
    )


def _add_verbosity(p: argparse.ArgumentParser, default) -> None:
    """-q / -v, given before or after the command (the command's parser leaves them unset unless given)."""
    group = p.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_true", default=default, help="errors only: no warnings, no progress bar")
    group.add_argument(
        "-v", "--verbose", action="count", default=default, help="informational lines on stderr too (-vv: debugging lines)"
    )


class _Version(argparse.Action):
    """`--version`: the package's version, Warp's and the devices Warp finds (Warp imported only here)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None):
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(version_text())
        parser.exit()


def version_text() -> str:
    """Three lines: warp-ricochet's version, Warp's, and each device Warp can use here."""
    lines = [f"{PROG} {__version__}"]
    try:
        from .device import warp

        wp = warp()
    except Exception as exc:  # Warp missing or broken: say so rather than fail
        return "\n".join(lines + [f"Warp: not usable here ({_one_line(exc)})"])
    lines.append(f"Warp {wp.__version__}")
    lines.append("devices: " + ", ".join(f"{d.alias} ({d.name})" for d in wp.get_devices()))
    return "\n".join(lines)


class _Parser(argparse.ArgumentParser):
    """argparse, its usage errors as the one line the README promises (`warp-ricochet: error: ...`), exit 2."""

    def error(self, message):
        _error(f"{message} (see {self.prog} --help)")
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog=PROG,
        description="Shotgun pellet ricochet (Zohdi 2021) in NVIDIA Warp kernels. SI units throughout.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--version", action=_Version, help="show the version of warp-ricochet and Warp, and the devices available, and exit"
    )
    _add_verbosity(parser, None)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    _add_subparsers(sub)
    return parser


def _add_subparsers(sub) -> None:

    p = sub.add_parser(
        "run",
        help="run one scene and print a summary of its statistics",
        description="Run every pellet of a scene, write HDF5 (with -o) and print a summary.",
    )
    _add_scene_options(p)
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the interrupted run left in OUT.h5.partial (the same scene, --set overrides and "
        "device); the result is bitwise that of an uninterrupted run",
    )
    _add_units(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser(
        "sweep",
        help="run a scene over a parameter sweep and print Tables 1-3",
        description="Run a scene at every point of a parameter sweep, write one HDF5 file "
        "(with -o) and print Tables 1-3 like `report`.",
        epilog="example: --param surfaces.0.mu_s=0:0.5:0.05 --tie surfaces.0.mu_d=0.9*",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_scene_options(p)
    p.add_argument(
        "--param",
        dest="params",
        action="append",
        required=True,
        metavar="KEY=START:STOP:STEP|a,b,c",
        help="a swept key: an inclusive range or a list of values (repeatable: cartesian product)",
    )
    p.add_argument(
        "--tie",
        dest="ties",
        action="append",
        default=[],
        metavar="KEY=F*[PARAM]",
        help="set KEY to F times a swept parameter at each point (PARAM may be left out when "
        "one parameter is swept), e.g. surfaces.0.mu_d=0.9*",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the interrupted sweep left in OUT.h5.partial/ (the same scene, --set, --param, "
        "--tie and device); the result is bitwise that of an uninterrupted sweep",
    )
    _add_report_options(p)
    _add_units(p)
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser(
        "report",
        help="print Tables 1-3 of the paper from an output file",
        description="Print Tables 1-3 (Zohdi 2021 layout) from a run or sweep HDF5 file.",
    )
    p.add_argument(
        "files",
        metavar="OUT.h5",
        nargs="+",
        help="a run or sweep file written by warp-ricochet; several: their Table 3 side by side "
        "(the same sweep, e.g. in vacuum and in air)",
    )
    _add_report_options(p)
    p.add_argument(
        "--html",
        metavar="OUT.html",
        help="write a self-contained HTML report of one run file instead (figures embedded; needs the report extra)",
    )
    p.add_argument("--overwrite", action="store_true", help="with --html: replace OUT.html if it exists")
    _add_units(p)
    p.set_defaults(func=cmd_report)

    p = sub.add_parser(
        "xdmf",
        help="write the XDMF sidecar (OUT.xmf) that opens a run or sweep file in ParaView",
        description="Write OUT.xmf beside OUT.h5: an XDMF 2 description of its point clouds, surfaces "
        "and trajectory frames that ParaView and VTK open (runs and sweeps write it when "
        'they complete; docs/output.md, "ParaView").',
    )
    p.add_argument("file", metavar="OUT.h5", help="a run or sweep file written by warp-ricochet")
    p.add_argument("--overwrite", action="store_true", help="replace OUT.xmf if it exists")
    p.set_defaults(func=cmd_xdmf)
    _add_plot_and_example(sub)
    for p in sub.choices.values():
        _add_verbosity(p, argparse.SUPPRESS)


def _add_plot_and_example(sub) -> None:
    p = sub.add_parser(
        "plot",
        help="draw PNG plots of run and sweep files (needs the plot extra: matplotlib)",
        description="Write PNGs of run and sweep files: for a run, where pellets land seen from "
        "above (density and energy), the range distribution with its survival curve, "
        "energy against distance; for sweeps, <L> with the L- to L+ band over the "
        "swept key and each point's survival curve (several sweeps side by side).",
        epilog="example: warp-ricochet plot sweep.h5 sweep-air.h5 -o plots/",
    )
    p.add_argument("files", metavar="OUT.h5", nargs="+", help="run or sweep files written by warp-ricochet")
    p.add_argument(
        "-o", "--output", metavar="DIR", help="folder for the PNGs (made if missing; default: the first file's folder)"
    )
    p.add_argument("--overwrite", action="store_true", help="replace PNGs that exist")
    p.set_defaults(func=cmd_plot)

    p = sub.add_parser(
        "example",
        help="list the example scenes, or write or print one",
        description="Without NAME, list the example scenes installed with the package; with NAME, "
        "print its TOML, or write it to PATH with -o.",
        epilog="example: warp-ricochet example paper -o paper.toml",
    )
    p.add_argument("name", metavar="NAME", nargs="?", help="an example's name (e.g. paper)")
    p.add_argument("-o", "--output", metavar="PATH", help="write the scene here instead of printing it")
    p.add_argument("--overwrite", action="store_true", help="replace PATH if it exists")
    p.set_defaults(func=cmd_example)

    p = sub.add_parser(
        "export",
        help="write a run's danger-area outlines (GeoJSON) and map layers (GeoTIFF) (needs the gis extra)",
        description="Write the danger-area outline of every threshold and containment p of a run with a "
        "hazard map as GeoJSON, and its map layers as a GeoTIFF: in the site's CRS when the scene "
        'gives [hazard.site], else in local coordinates (docs/hazard.md, "Outlines and GIS files").',
        epilog="example: warp-ricochet export run.h5 --geojson danger.geojson --geotiff map.tif --p 1e-3",
    )
    p.add_argument("file", metavar="RUN.h5", help="a run file written by warp-ricochet, with a hazard map")
    p.add_argument("--geojson", metavar="OUT.geojson", help="the outlines: one feature per threshold and p")
    p.add_argument("--geotiff", metavar="OUT.tif", help="the map layers: landings, passes, exposure per threshold")
    p.add_argument(
        "--p",
        dest="fractions",
        action="append",
        type=float,
        metavar="P",
        help="a containment p in (0, 1): the share of the exposure left outside (repeatable; default: the run's hazard.fractions)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace output files that exist")
    p.set_defaults(func=cmd_export)

    p = sub.add_parser(
        "loads",
        help="list the shot-load catalogue: shot sizes per numbering system and materials, with sources",
        description="List what [shot] load = {size, material, charge} takes: the shot sizes of each numbering "
        "system (US, UK, IT) in mm and inches, and the materials with their densities, each with its "
        'published source (docs/scenes.md, "Shot loads").',
    )
    p.set_defaults(func=cmd_loads)


# ---------------------------------------------------------------------------------------------- commands


def _device_name(api, name, client=None) -> str:
    if client is not None:  # the workers' device (this process may have none)
        from .cluster import remote_name

        return remote_name(client, name)
    return str(api.resolve_device(name))


def _client(args, check=None):
    """The Dask client of --cluster or --scheduler (its dashboard's address on stderr), before any
    work and before Warp starts here, after `check()` (the command's checks that need no device:
    a refusal comes before the cluster starts); a null context without them."""
    if args.cluster is None and args.scheduler is None:
        return contextlib.nullcontext()
    from .cluster import session

    if check is not None:
        check()
    return session(args.cluster, args.scheduler, args.device, announce=None if args.quiet else sys.stderr)


def cmd_run(args) -> int:
    from .progress import ProgressBar
    from .report import format_run_summary
    from .scene import load_scene

    scene = load_scene(args.scene, args.overrides)  # before warp: a bad scene fails fast
    from . import api

    interrupts.check()
    output = args.output if args.output is not None else scene.output.path
    check = functools.partial(api.check_run, scene, output, overwrite=args.overwrite, resume=args.resume, on_cluster=True)
    with _client(args, check) as client, ProgressBar("run", enabled=False if args.quiet else None) as bar:
        stats = api.run(
            scene, args.output, args.device, overwrite=args.overwrite, progress=bar, resume=args.resume, client=client
        )
        device = _device_name(api, args.device, client)
    args.completed = output  # a signal from here on: the result is complete (None: statistics only)
    interrupts.check(completed_path=output)
    sys.stdout.write(format_run_summary(stats, output, device, scene))
    return 0


def cmd_sweep(args) -> int:
    from .progress import ProgressBar
    from .report import format_tables, read_results, results_from_sweep
    from .scene import load_scene, parse_sweep, parse_tie

    scene = load_scene(args.scene, args.overrides)
    set_keys = {str(o).partition("=")[0].strip() for o in args.overrides}
    params = {}
    for spec in args.params:
        key, values = parse_sweep(spec)
        if key in params:
            raise SceneError(key, spec, "is swept twice; give each --param key once")
        if key in set_keys:  # the sweep would replace the --set value at every point
            raise SceneError(key, spec, "is given with --set too; give it either --set or --param")
        params[key] = values
    ties = [parse_tie(spec) for spec in args.ties]
    from . import api

    output = args.output if args.output is not None else scene.output.path
    kw = dict(overwrite=args.overwrite, resume=args.resume, on_cluster=True)
    check = functools.partial(api.check_sweep, scene, params, ties, output, **kw)
    with _client(args, check) as client, ProgressBar("sweep", enabled=False if args.quiet else None) as bar:
        results = api.sweep(
            scene,
            params,
            ties,
            args.output,
            args.device,
            overwrite=args.overwrite,
            progress=bar,
            resume=args.resume,
            client=client,
        )
        device = _device_name(api, args.device, client)
    args.completed, args.completed_what = output, "sweep"  # a signal from here on: the sweep is complete
    interrupts.check(completed_path=output, completed_what="sweep")
    if output is not None:
        res = read_results(output)  # exactly what `report` prints
    else:
        res = results_from_sweep(results, params, ties, meta={"device": device, "scene_toml": scene.to_toml()})
    sys.stdout.write(format_tables(res, args.format, paper=args.paper))
    return 0


def cmd_report(args) -> int:
    from .report import ReportError, format_side_by_side, format_tables, read_results

    if args.html is not None:
        return _html_report(args)
    results = [read_results(path) for path in args.files]
    if len(results) == 1:
        sys.stdout.write(format_tables(results[0], args.format, paper=args.paper))
    elif args.paper:
        raise ReportError(args.files[1], "--paper compares one file with the paper; give one file")
    else:
        sys.stdout.write(format_side_by_side(results, args.format))
    return 0


def _html_report(args) -> int:
    from .report.html import HtmlError, write_html

    if len(args.files) > 1:
        raise HtmlError(args.html, f"the HTML report is of one run file; {len(args.files)} were given")
    if args.paper or args.format != "text":
        raise HtmlError(args.html, "--paper and --format are for the text report; give them without --html")
    print(f"wrote {write_html(args.files[0], args.html, overwrite=args.overwrite)}")
    return 0


def cmd_xdmf(args) -> int:
    from .io.xdmf import write_xdmf

    print(write_xdmf(args.file, overwrite=args.overwrite))
    return 0


def cmd_plot(args) -> int:
    from .report.plots import write_plots

    for png, why in write_plots(args.files, args.output, overwrite=args.overwrite):
        print(f"wrote {png}" if why is None else f"skipped {png}: {why}")
    return 0


def cmd_example(args) -> int:
    from .examples import example_text, examples

    if args.name is None:
        width = max(len(name) for name, _ in examples())
        for name, summary in examples():
            print(f"{name.ljust(width)}  {summary}")
        return 0
    text = example_text(args.name)
    if args.output is None:
        sys.stdout.write(text)
        return 0
    from .examples import write_example

    write_example(text, args.output, overwrite=args.overwrite)
    print(f"wrote {args.output}")
    return 0


def cmd_export(args) -> int:
    try:
        from .gis.export import export
    except ImportError as exc:
        raise RicochetError(f"export needs the gis extra ({exc.name} is missing): pip install 'warp-ricochet[gis]'") from None
    for path in export(args.file, args.geojson, args.geotiff, args.fractions, overwrite=args.overwrite):
        print(f"wrote {path}")
    return 0


def cmd_loads(args) -> int:
    from .scene.loads import catalogue_lines

    print("\n".join(catalogue_lines()))
    return 0


# ---------------------------------------------------------------------------------------------- main


def _one_line(text) -> str:
    """One line, at most MAX_MESSAGE characters (a huge key or path is not echoed whole)."""
    return shorten(" ".join(str(text).split()), MAX_MESSAGE)


def _os_message(exc: OSError) -> str:
    parts = [exc.strerror or _one_line(exc) or type(exc).__name__]
    for name in (exc.filename, exc.filename2):
        if name is not None:
            parts.append(repr(os.fsdecode(name)))
    return ": ".join(parts)


def _error(message: str) -> None:
    try:
        sys.stdout.flush()
    except (OSError, ValueError):
        pass
    print(f"{PROG}: error: {_one_line(message)}", file=sys.stderr)


class _OneLine(logging.Formatter):
    """`warp-ricochet: warning: ...` (the level in lower case), one line, like the errors."""

    def format(self, record):
        return f"{PROG}: {record.levelname.lower()}: {_one_line(record.getMessage())}"


LOGGERS = ("warp_ricochet", "py.warnings")


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Python warnings (PrecisionWarning, SceneWarning, ...) as log lines of `py.warnings`, as
    `logging.captureWarnings` does, without its file and line (they are the user's, not code's)."""
    logging.getLogger("py.warnings").warning("%s", message)


def configure_logging(verbose: int = 0, quiet: bool = False, stream=None) -> None:
    """The command's log lines on stderr: WARNING by default, ERROR with `quiet`, INFO with one
    `verbose`, DEBUG with two. Python warnings (e.g. PrecisionWarning) go through `py.warnings`."""
    if quiet:
        level = logging.ERROR
    else:
        level = (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)]
    handler = logging.StreamHandler(sys.stderr if stream is None else stream)
    handler.setFormatter(_OneLine())
    warnings.showwarning = _show_warning
    for name in LOGGERS:
        logger = logging.getLogger(name)
        for old in [h for h in logger.handlers if isinstance(h.formatter, _OneLine)]:
            logger.removeHandler(old)
        logger.addHandler(handler)
        logger.setLevel(level)
        logger.propagate = False


def main(argv=None) -> int:
    """Entry point of `warp-ricochet`; returns the exit status (argparse exits itself on usage errors).
    Ctrl-C and SIGTERM are requests the run acts on at safe points (`interrupts`): the output is
    closed and marked "interrupted", exit status 130."""
    args = build_parser().parse_args(argv)
    configure_logging(args.verbose or 0, args.quiet or False)
    try:
        with interrupts.honoured((signal.SIGINT, signal.SIGTERM)):
            status = _run_command(args)
    except KeyboardInterrupt:  # a signal after the command's last check (its result complete)
        print(f"{PROG}: interrupted{_kept(_completed(args))}", file=sys.stderr)
        status = 130
    _LATE["note"] = _kept(_completed(args))  # (entry: a signal after main returned)
    runfile = sys.modules.get("warp_ricochet.io.runfile")
    if runfile is not None and runfile.ABANDONED:  # HDF5 crashes in its exit handler after a failed close
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    return status


def _run_command(args) -> int:
    """The subcommand; every failure as one line on stderr and an exit status."""
    try:
        if getattr(args, "paper", False) and getattr(args, "units", "metric") != "metric":
            raise RicochetError(
                f"--units = {args.units!r}: --paper compares with the paper's tables in SI; give it without --units"
            )
        with display.using(getattr(args, "units", None)):  # what is printed; files stay SI
            status = args.func(args)
        # a signal after the run's last safe point (while its summary was printed)
        interrupts.check(completed_path=getattr(args, "completed", None), completed_what=getattr(args, "completed_what", "run"))
        return status
    except RicochetError as exc:  # before OSError: OutputError is both
        _error(str(exc))
        return 2
    except BrokenPipeError:  # stdout closed early (| head): quietly, and keep Python's flush at exit quiet
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return 1
    except OSError as exc:
        _error(_os_message(exc) + _kept(exc))
        return 1
    except KeyboardInterrupt as exc:
        print(f"{PROG}: interrupted{_kept(exc)}", file=sys.stderr)
        return 130


def _completed(args) -> KeyboardInterrupt:
    """A request after the command's last check, noting where its completed result is (`_kept`)."""
    exc = KeyboardInterrupt()
    exc.completed_path = getattr(args, "completed", None)
    exc.completed_what = getattr(args, "completed_what", "run")
    return exc


def _kept(exc) -> str:
    """Where the chunks completed before a failure are (set by the output file when it was open)."""
    completed = getattr(exc, "completed_path", None)
    if completed is not None:
        return f"; the {getattr(exc, 'completed_what', 'run')} had completed: its result is in {completed}"
    partial = getattr(exc, "partial_path", None)
    if partial is None:
        return ""
    what = getattr(exc, "resume_command", "run")  # "sweep" for a sweep's folder (api._sweep_kept)
    resumable = f" (warp-ricochet {what} ... --resume continues the {what})" if getattr(exc, "resumable", False) else ""
    return f"; the chunks completed are in {partial}{resumable}"


_LATE = {"note": ""}  # what `entry` adds to "interrupted" for a signal after `main` returned


def entry() -> int:
    """The console script and `python -m warp_ricochet.cli`: `main` with Ctrl-C and SIGTERM recorded
    from the start to the process's end (`interrupts.honour_until_exit`), then the exit: Python's
    exit functions, and a request that no safe point acted on (one after the command returned)
    ends as the others do: exit status 130 and the one line saying where the result is. The process
    then ends at once (os._exit, after flushing), skipping the interpreter's teardown (~0.5 s in
    which a signal could only have been ignored or ended the process without a word)."""
    if threading.current_thread() is not threading.main_thread():
        return main()
    interrupts.honour_until_exit((signal.SIGINT, signal.SIGTERM))
    status = main()
    atexit._run_exitfuncs()  # (e.g. Warp's)
    if not _flush_all() and status == 0:
        status = 120  # what CPython exits with when it cannot flush stdout at its end
    if interrupts.pending() and status == 0:  # (a failure's status and line stand)
        print(f"{PROG}: interrupted{_LATE['note']}", file=sys.stderr)
        _flush_all()
        status = 130
    os._exit(status)  # (a signal from here on is recorded and dropped: the process is ending)


def _flush_all() -> bool:
    """Flush Python's standard streams and the C library's (os._exit does neither); whether
    standard output could be flushed."""
    flushed = True
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            flushed = flushed and stream is not sys.stdout
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):
        pass
    return flushed


if __name__ == "__main__":
    raise SystemExit(entry())
