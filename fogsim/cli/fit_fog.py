"""``fogsim fit-fog``: fit the scatter fog model on path-traced renders (:mod:`fogsim.bench.fit_fog`)."""
from __future__ import annotations


def add_parsers(sub) -> None:
    p = sub.add_parser("fit-fog", help="fit the scatter fog model's parameters on path-traced renders "
                       "(fogsim bench fog-physics folders) and write its parameter JSON")
    p.add_argument("runs", nargs="+", metavar="RUN_DIR",
                   help="fogsim bench fog-physics --out folders (clear + two volumetric runs each)")
    p.add_argument("--out", default="scatter_params.json",
                   help="the parameter file to write (fogsim ships fogsim/fog/scatter_params.json)")
    p.add_argument("--start", metavar="FILE", help="start the search from this parameter file (e.g. the shipped "
                   "one, for a refit on more frames; default: forward scatter on, the rest off)")
    p.add_argument("--glow-only", action="store_true", help="refit only the glow on night runs, every other "
                   "parameter kept from --start (default: the shipped file), whose record gains these runs")
    p.add_argument("--quiet", action="store_true", help="print only errors and the summary line")
    p.set_defaults(run=_run)


def _run(args) -> int:
    from fogsim.bench.fit_fog import run

    return run(args)
