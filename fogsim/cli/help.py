"""The one help formatter of every ``fogsim`` command (:func:`use_everywhere` sets it on the whole parser tree).

* A default is shown once: ``(default: X)`` is added only where the help text does not already say its
  default, and never for a default that is not a value (None, False, an empty string).
* A long usage is short: a command with many options prints ``usage: PROG --out OUT … [options]`` (its
  required options and positionals, then ``[options]``) instead of every flag twice.
* Descriptions keep their line breaks (module docstrings are written as paragraphs and examples).
"""
from __future__ import annotations

import argparse
import re

__all__ = ["HelpFormatter", "states_default", "use_everywhere"]

#: a help text that already says its default ("(default: paper)", "default 19", "…; default frame")
_SAYS_DEFAULT = re.compile(r"\bdefault", re.IGNORECASE)
#: beyond this many options a usage line lists only what is required
SHORT_USAGE_ABOVE = 8


def states_default(action: argparse.Action) -> bool:
    """True when the formatter adds ``(default: X)`` to ``action``'s help: it takes a value, its default is a
    value worth saying, and its help does not say a default already."""
    default = action.default
    if action.help in (None, argparse.SUPPRESS) or action.nargs == 0 or not action.option_strings:
        return False
    if default is None or default is argparse.SUPPRESS or default is False or default == "":
        return False
    return "%(default)" not in action.help and not _SAYS_DEFAULT.search(action.help)


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """fogsim's help layout (the module docstring): defaults said once, short usage, descriptions as written."""

    def __init__(self, prog: str, indent_increment: int = 2, max_help_position: int = 30, width: int | None = None):
        super().__init__(prog, indent_increment, max_help_position, width)

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        return text + " (default: %(default)s)" if states_default(action) else text

    def add_usage(self, usage, actions, groups, prefix=None):
        options = [a for a in actions if a.option_strings and a.help is not argparse.SUPPRESS]
        if usage is None and len(options) > SHORT_USAGE_ABOVE:
            parts = ["%(prog)s"]
            for a in actions:
                if a.option_strings and a.required:
                    parts.append(f"{a.option_strings[-1]} {self._metavar_formatter(a, a.dest.upper())(1)[0]}")
                elif not a.option_strings:  # positionals (a sub-command's name) as argparse writes them
                    parts.append(self._metavar_formatter(a, a.dest)(1)[0])
            usage = " ".join(parts) + " [options]"
        super().add_usage(usage, actions, groups, prefix)


def use_everywhere(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """``parser`` and every sub-command parser below it formatted by :class:`HelpFormatter`; returns it."""
    parser.formatter_class = HelpFormatter
    for action in parser._actions:  # argparse keeps sub-parsers only here
        if isinstance(action, argparse._SubParsersAction):
            for sub in set(action.choices.values()):
                use_everywhere(sub)
    return parser
