"""MkDocs hooks (``hooks:`` in ``mkdocs.yml``): the parts of the manual that are generated, not written.

* ``docs/cli.md``: the marker :data:`CLI_MARKER` is replaced by the reference of every ``fogsim``
  command and sub-command — summary, usage, description and options — taken from
  :func:`fogsim.cli.build_parser` of *this* checkout at build time, so it cannot drift from the code.
* ``CONTRIBUTING.md`` and ``CHANGELOG.md`` live at the repository root (one copy each: the layout
  tree is CONTRIBUTING.md's); they become the site pages ``contributing.md`` and ``changelog.md``,
  and a page's link ``../CONTRIBUTING.md`` (right when the page is read on GitHub) is pointed at them.

:func:`cli_reference` needs no MkDocs (``tests/test_docs.py`` calls it directly).
"""
from __future__ import annotations

import argparse
import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLI_MARKER = "<!-- fogsim-cli-reference -->"
ROOT_PAGES = {"CONTRIBUTING.md": "contributing.md", "CHANGELOG.md": "changelog.md"}
HELP_COLUMNS = "100"  # argparse wraps help to the terminal width: fixed, so the page is the same everywhere


def commands(parser: argparse.ArgumentParser, path: tuple[str, ...] = ("fogsim",), summary: str = ""):
    """``(path, parser, summary)`` of ``parser`` and of every sub-command below it, depth first, in the
    parser's order; ``summary`` is the one-line ``help=`` the parent gave the sub-command."""
    yield path, parser, summary
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            for name, sub in action.choices.items():
                yield from commands(sub, path + (name,), helps.get(name, ""))


def anchor(path: tuple[str, ...]) -> str:
    """The heading id MkDocs' toc extension gives the heading ``" ".join(path)``."""
    return re.sub(r"[^a-z0-9]+", "-", " ".join(path).lower()).strip("-")


def cli_reference() -> str:
    """Markdown for every command of ``fogsim.cli.build_parser()``: an index, then one section each."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))  # document this checkout's parser, not an installed fogsim
    from fogsim.cli import build_parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = HELP_COLUMNS
    try:
        found = list(commands(build_parser()))
        index = ["| command | what it does |", "|---|---|"]
        sections = []
        for path, parser, summary in found:
            name = " ".join(path)
            text = summary.replace("%%", "%").replace("|", "\\|") or (parser.description or "").split("\n")[0]
            index.append(f"| [`{name}`](#{anchor(path)}) | {text} |")
            heading = "##" if len(path) <= 2 else "###"  # the page title is the one #
            sections += [f"{heading} {name}", ""] + ([summary.replace("%%", "%"), ""] if summary else [])
            sections += ["```text", parser.format_help().rstrip(), "```", ""]
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old
    return "\n".join(index + [""] + sections)


# ----------------------------------------------------------------------------- MkDocs events
def on_files(files, config):
    """Add the repository-root pages (CONTRIBUTING.md, CHANGELOG.md) to the site."""
    from mkdocs.structure.files import File

    for source, page in ROOT_PAGES.items():
        if (ROOT / source).is_file() and files.get_file_from_path(page) is None:
            files.append(File.generated(config, page, abs_src_path=str(ROOT / source)))
    return files


def on_page_markdown(markdown, page, config, files):
    """Fill in the CLI reference; point links to the repository-root pages at their site pages."""
    if page.file.src_uri == "cli.md":
        if CLI_MARKER not in markdown:
            raise ValueError(f"docs/cli.md lost its marker {CLI_MARKER}: the CLI reference has nowhere to go")
        markdown = markdown.replace(CLI_MARKER, cli_reference())
    for source, target in ROOT_PAGES.items():
        markdown = markdown.replace(f"](../{source}", f"]({target}")
    return markdown
