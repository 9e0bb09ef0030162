"""The README is a front door and the manual cannot drift from the code.

* README.md ≤ 120 lines, with the two commands exactly and links that resolve.
* Every ``fogsim …`` command in a ``bash`` block of the README or a docs page parses with the real
  parser (a renamed or removed flag fails here), and the ``python`` blocks of the docs run.
* The generated CLI reference (``scripts/mkdocs_hooks.py``) has a section, the usage and every option
  of every command and sub-command ``fogsim.cli.build_parser()`` has.
* ``mkdocs build --strict`` passes (skipped without MkDocs): a broken link or anchor, a nav entry without
  its page or a page without its nav entry fails it.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.glob("*.md"))
COMMAND_1 = ('python3 -m venv .venv && .venv/bin/pip install -e ".[blender]" && '
             '.venv/bin/fogsim render --out out/default')
COMMAND_2 = "bash scripts/test.sh"
NOT_RUN = "# not run by the docs test:"
OPTIONAL_EXTRAS = {"albumentations", "torch", "torchvision", "bpy", "ultralytics", "pycocotools", "pyarrow"}
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.S | re.M)


def hooks():
    spec = importlib.util.spec_from_file_location("mkdocs_hooks", ROOT / "scripts" / "mkdocs_hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def blocks(path: Path, language: str) -> list[str]:
    return [body for lang, body in FENCE.findall(path.read_text(encoding="utf-8")) if lang == language]


def walk(parser: argparse.ArgumentParser, path=("fogsim",)):
    """Every (command path, parser) below ``parser``, found independently of the hook's own walk."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from walk(sub, path + (name,))


# ----------------------------------------------------------------------------- the README
def test_readme_is_a_front_door():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 120  # results live on their pages (one line and a link each)
    lines = [line.strip() for line in text.splitlines()]
    assert COMMAND_1 in lines and COMMAND_2 in lines  # unchanged: CI and newcomers run exactly these
    assert "![contact sheet" in text


@pytest.mark.parametrize("page", [README] + PAGES, ids=lambda p: p.name)
def test_relative_links_resolve(page):
    """Links as GitHub reads them (mkdocs --strict checks the site's, anchors included)."""
    text = FENCE.sub("", page.read_text(encoding="utf-8"))
    targets = re.findall(r"\]\(([^)\s]+)\)", text)
    assert targets or page.name == "cli.md"
    for target in targets:
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        path = (page.parent / target.split("#")[0]).resolve()
        assert path.exists(), f"{page.name}: link to {target} ({path}) does not resolve"


# ----------------------------------------------------------------------------- commands shown
def shown_commands() -> list[tuple[str, list[str]]]:
    """``(where, argv after "fogsim")`` of every fogsim command in a bash block of README / docs."""
    found = []
    for page in [README] + PAGES:
        for body in blocks(page, "bash"):
            for line in body.replace("\\\n", " ").splitlines():
                wrapped = re.search(r"--wrap '([^']*)'", line)
                for part in ([wrapped.group(1)] if wrapped else line.split("&&")):
                    words = shlex.split(part, comments=True)
                    if words[:1] in (["fogsim"], [".venv/bin/fogsim"]):
                        found.append((f"{page.name}: {part.strip()}", words[1:]))
                    elif words[:4] == ["blender", "-b", "-P", "scripts/render_batch.py"]:
                        found.append((f"{page.name}: {part.strip()}", ["render"] + words[5:]))
    return found


def test_documented_commands_are_found():
    where = {w.split(":")[0] for w, _ in shown_commands()}
    assert {"README.md", "rendering.md", "real-data.md", "depth.md", "study.md"} <= where
    assert len(shown_commands()) >= 40


@pytest.mark.parametrize("where,argv", shown_commands(), ids=[w for w, _ in shown_commands()])
def test_documented_command_parses(where, argv):
    from fogsim.cli import build_parser

    parser = build_parser()
    for _, p in walk(parser):
        p.allow_abbrev = False  # a flag shown must be spelt in full: a renamed one is not a prefix match
    said = io.StringIO()
    with contextlib.redirect_stderr(said), contextlib.redirect_stdout(io.StringIO()):
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:
            pytest.fail(f"{where}\n  does not parse (exit {exc.code}): {said.getvalue().strip()}")
    assert callable(args.run)


@pytest.mark.parametrize("page", [p for p in [README] + PAGES if blocks(p, "python")], ids=lambda p: p.name)
def test_python_examples_run(page):
    """A page's Python blocks run in order in one namespace (a page reads as one session). A block
    whose first line is ``# not run by the docs test: <why>`` is only compiled; an optional extra
    that is not installed skips the page."""
    namespace = {"__name__": "docs_example"}
    for code in blocks(page, "python"):
        compiled = compile(code, str(page), "exec")
        if code.startswith(NOT_RUN):
            assert len(code.splitlines()[0]) > len(NOT_RUN) + 10, f"{page.name}: say why the block is not run"
            continue
        try:
            exec(compiled, namespace)
        except ModuleNotFoundError as exc:
            if exc.name in OPTIONAL_EXTRAS:
                pytest.skip(f"{page.name}: {exc.name} is not installed")
            raise


# ----------------------------------------------------------------------------- the CLI reference
def test_cli_reference_lists_every_command():
    from fogsim.cli import build_parser

    page = hooks().cli_reference()
    headings = re.findall(r"^#{2,3} (fogsim[\w -]*)$", page, re.M)
    expected = [" ".join(path) for path, _ in walk(build_parser())]
    assert headings == expected  # every command, each once, in the parser's order
    assert len(expected) >= 19 and "fogsim bench fog-physics" in expected and "fogsim depth score" in expected
    for path, parser in walk(build_parser()):
        assert f"usage: {' '.join(path)}" in page
        for action in parser._actions:
            for option in action.option_strings:
                assert re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", page), f"{' '.join(path)} {option}"


def test_cli_page_keeps_its_marker():
    assert hooks().CLI_MARKER in (DOCS / "cli.md").read_text(encoding="utf-8")


# ----------------------------------------------------------------------------- the built site
def test_mkdocs_build_strict(tmp_path):
    pytest.importorskip("mkdocs", reason="the docs extra is not installed")
    pytest.importorskip("material", reason="mkdocs-material (the docs extra) is not installed")
    site = tmp_path / "site"
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)], cwd=ROOT,
                         capture_output=True, text=True, timeout=300, env=os.environ | {"NO_MKDOCS_2_WARNING": "1"})
    assert res.returncode == 0, res.stdout + res.stderr
    assert "WARNING" not in res.stderr, res.stderr
    for page in PAGES:
        built = site / ("index.html" if page.stem == "index" else f"{page.stem}/index.html")
        assert built.is_file(), f"{page.name} was not built"
    cli = (site / "cli" / "index.html").read_text(encoding="utf-8")
    from fogsim.cli import build_parser

    for path, _ in walk(build_parser()):
        assert f'id="{"-".join(path)}"' in cli, " ".join(path)
    assert "Dependency rules" in (site / "contributing" / "index.html").read_text(encoding="utf-8")
    assert (site / "contact_sheet.png").is_file()


def test_extras_are_installed_together_as_the_test_script_does():
    """The dependency page never tells to install one extra on its own into the bpy venv (pip would
    then upgrade numpy to 2.x and put opencv-python over the contrib build): every install command
    there that names an extra beside torch names the blender extra too, and its 'together' line names
    the extras scripts/test.sh installs (less dev and docs)."""
    page = (DOCS / "dependencies.md").read_text()
    script = (ROOT / "scripts" / "test.sh").read_text()
    tested = set(re.search(r'-e "\.\[([a-z,]+)\]"', script).group(1).split(",")) - {"dev", "docs"}
    commands = re.findall(r'pip install[^`]*-e "\.\[([a-z,]+)\]"', page)
    assert commands, "no install command found"
    for extras in commands:
        assert "blender" in extras.split(","), f'pip install -e ".[{extras}]" alone would break bpy\'s pins'
    assert tested in [set(e.split(",")) for e in commands]
    assert "Install the extras together" in page
