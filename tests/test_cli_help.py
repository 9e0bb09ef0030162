"""Every command's ``--help`` (issue 47, point 4): a default said once — never ``(default: None)``, never a
default added to a help that already names one — a short usage line, and ``fogsim fog``'s inputs first."""
from __future__ import annotations

import argparse
import re

import pytest

from fogsim.cli import build_parser
from fogsim.cli.help import HelpFormatter, states_default


def walk(parser: argparse.ArgumentParser, path=("fogsim",)):
    yield " ".join(path), parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from walk(sub, path + (name,))


COMMANDS = dict(walk(build_parser()))


@pytest.fixture(autouse=True)
def columns(monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_no_null_and_no_doubled_defaults(name):
    parser = COMMANDS[name]
    assert parser.formatter_class is HelpFormatter
    text = parser.format_help()
    for empty in ("(default: None)", "(default: False)", "(default: )", "(default: ==SUPPRESS==)"):
        assert empty not in text, f"{name} --help: {empty}"
    flat = " ".join(text.split())  # the help as one line: a default wrapped across lines is still one
    assert not re.search(r"\(default[^()]*\)\s*\(default", flat), name
    formatter = parser._get_formatter()
    for action in parser._actions:
        if not action.help or action.help == argparse.SUPPRESS:
            continue
        shown = formatter._expand_help(action)
        said = re.search(r"\bdefault", action.help, re.IGNORECASE)
        added = shown.count("(default: ") - action.help.count("(default: ")
        # a default is added only where the help says none, and then exactly once
        assert added == (1 if states_default(action) else 0) and not (said and added), (name, action.dest, shown)


def test_a_value_default_is_said_and_a_stated_one_is_not_repeated():
    fog = COMMANDS["fogsim fog"].format_help()
    flat = " ".join(fog.split())
    assert "(default: FRONT)" in flat and "(default: koschmieder)" in flat  # values the help did not name
    assert "kernel size in pixels, odd (default: 19)" in flat
    assert flat.count("(default: paper)") == 1 and "(default: paper) (default" not in flat


def test_fog_help_is_short_and_lists_its_inputs_first():
    text = COMMANDS["fogsim fog"].format_help()
    lines = text.splitlines()
    assert lines[0] == "usage: fogsim fog --out OUT [options]"
    headings = [ln for ln in lines if ln and not ln.startswith(" ") and ln.endswith(":")]
    assert headings[:3] == ["options:", "input (one of; none with --finalize-only):", "depth:"]
    inputs = text[text.index("input (one of"):text.index("\ndepth:")]
    for flag in ("--input", "--cityscapes", "--waymo", "--kitti", "--stf", "--points", "--split", "--cameras"):
        assert f"  {flag} " in inputs, flag
    assert "--split" not in text[text.index("options:"):text.index("input (one of")]
    assert len(lines) < 210  # was 253 with every flag twice in the usage and 34 × "(default: None)"


def test_a_short_command_keeps_its_full_usage():
    text = COMMANDS["fogsim demo"].format_help()
    assert "[options]" not in text.splitlines()[0]
