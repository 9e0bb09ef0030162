"""``fogsim`` — the one front door: ``render | fog | ila | depth | study | bench | fit-fog | lidar-fit |
lidar-compare | levels | demo | schema | export``.

Every subcommand's ``--help`` works without Blender, torch or Ultralytics: they are imported
only when a command needs them. Errors end a command with one line (never a traceback) and
the exit code of :func:`fogsim.errors.exit_code`: 0 done, 1 some items failed (each named),
2 usage or setup error, 130 interrupted.
"""
from __future__ import annotations

import argparse
import sys

from fogsim._version import __version__
from fogsim.errors import run_command


def build_parser() -> argparse.ArgumentParser:
    from fogsim.cli import bench, demo, depth, export, fit_fog, fog, ila, lidar_fit, render, schema, study
    from fogsim.cli.help import use_everywhere

    parser = argparse.ArgumentParser(prog="fogsim", description="Labeled images in fog: render street scenes, "
                                     "fog rendered and real datasets, train and evaluate detectors per fog level.")
    parser.add_argument("--version", action="version", version=f"fogsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    render.add_parsers(sub)
    fog.add_parsers(sub)
    demo.add_parsers(sub)
    ila.add_parsers(sub)
    depth.add_parsers(sub)
    study.add_parsers(sub)
    bench.add_parsers(sub)
    fit_fog.add_parsers(sub)
    lidar_fit.add_parsers(sub)
    schema.add_parsers(sub)
    export.add_parsers(sub)
    return use_everywhere(parser)


def positional_names(parser: argparse.ArgumentParser, args: argparse.Namespace) -> frozenset[str]:
    """The names of the arguments given without a flag in the command ``args`` ran (``dataset`` of ``export
    nuscenes``; ``study --dataset`` is a flag): the chosen subcommand at each level, by its ``dest``."""
    names = set()
    for action in parser._actions:  # argparse keeps its actions there; no public accessor
        if isinstance(action, argparse._SubParsersAction):
            chosen = action.choices.get(getattr(args, action.dest, None))
            if chosen is not None:
                names |= positional_names(chosen, args)
        elif not action.option_strings:
            names.add(action.dest)
    return frozenset(names)


def main(argv: list[str] | None = None) -> int:
    from fogsim.io.paths import with_checked_paths

    parser = build_parser()
    args = parser.parse_args(argv)
    return run_command(with_checked_paths(args.run, positional_names(parser, args)), args)


if __name__ == "__main__":
    sys.exit(main())
