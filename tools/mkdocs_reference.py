"""MkDocs hook: a reference page per command of ``gistools``, made from the command line itself.

Each page (``reference/<command>.md``, listed under "Command reference" in the nav) holds the command's usage line,
its text and a table of its options, taken from the click command, which is made from the parameters' one
declaration (``gistools.parameters``): the same rows, in the same order, with the same words as
``gistools COMMAND --help`` (tests/test_docs.py compares the built pages with ``--help``).
"""

from __future__ import annotations

import html
import inspect
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SECTION = "Command reference"


def _commands() -> dict:
    """{page name: (words after ``gistools``, click command)}: every command, and each command of a group
    (``gistools aquifer model`` is the page ``aquifer-model``)."""
    import click

    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from gistools.cli.main import all_commands

    found = {}
    for name, cmd in sorted(all_commands().items()):
        if isinstance(cmd, click.Group):
            for sub, subcmd in sorted(cmd.commands.items()):
                found[f"{name}-{sub}"] = (f"{name} {sub}", subcmd)
        else:
            found[name] = (name, cmd)
    return found


def _context(words: str):
    import click

    from gistools.cli.main import cli

    ctx = click.Context(cli, info_name="gistools")
    group = cli
    for word in words.split():
        cmd = group.get_command(ctx, word)
        ctx = click.Context(cmd, info_name=word, parent=ctx)
        group = cmd
    return ctx


def _cell(text: str) -> str:
    """Text for a Markdown table cell: escaped, pipes kept as text, one line."""
    return html.escape(" ".join(str(text).split()), quote=False).replace("|", "\\|")


def options_rows(words: str) -> list[tuple[str, str]]:
    """``(option, help)`` rows of ``gistools WORDS --help``'s options, as click prints them (unwrapped)."""
    import click

    ctx = _context(words)
    cmd = ctx.command
    rows = []
    for param in cmd.get_params(ctx):
        if not isinstance(param, click.Option):  # arguments are in the usage line, as in --help
            continue
        record = param.get_help_record(ctx)
        if record:
            rows.append((record[0], record[1]))
    return rows


def page(command: str) -> str:
    """The Markdown of the reference page of ``command`` (its words after ``gistools``: "rasters", "aquifer model")."""
    ctx = _context(command)
    cmd = ctx.command
    usage = " ".join(cmd.collect_usage_pieces(ctx))
    text = inspect.cleandoc(cmd.help or "").split("\f")[0]
    lines = [f"# gistools {command}", "", "```text", f"gistools {command} {usage}", "```", ""]
    lines += _paragraphs(text)
    lines += ["", "## Options", "", "| option | what it does |", "|---|---|"]
    lines += [f"| <code>{_cell(name).replace(chr(92) + '|', '&#124;')}</code> | {_cell(help_)} |"
              for name, help_ in options_rows(command)]
    lines += ["", f"This table is `gistools {command} --help`. Units, defaults that follow the data's unit and "
                  "the layer syntax are explained in [Concepts](../concepts.md).", ""]
    return "\n".join(lines)


def _paragraphs(text: str) -> list[str]:
    """click's help text as Markdown: paragraphs kept, the examples (``$ ...`` lines) as a code block."""
    out, code = [], False
    for line in text.splitlines():
        stripped = line.strip()
        if stripped == "\b":  # click's mark of a paragraph it does not rewrap
            continue
        if stripped.startswith("$ ") or (code and out[-1].endswith("\\")):  # a command, or its next line
            if not code:
                out += ["", "```text"]
                code = True
            out.append(stripped[2:] if stripped.startswith("$ ") else "    " + stripped)
            continue
        if code:
            out += ["```", ""]
            code = False
        out.append(html.escape(stripped, quote=False))
    if code:
        out.append("```")
    return out


def on_config(config, **kwargs):
    """Add the "Command reference" section (one page per command) to the nav."""
    commands = _commands()
    nav = [entry for entry in config["nav"] if not (isinstance(entry, dict) and SECTION in entry)]
    at = next((i for i, e in enumerate(nav) if isinstance(e, dict) and "Concepts" in e), len(nav))
    nav.insert(at, {SECTION: [{f"gistools {words}": f"reference/{name}.md"} for name, (words, _) in commands.items()]})
    config["nav"] = nav
    return config


def on_files(files, config, **kwargs):
    """The reference pages, generated (no file of docs/ holds them)."""
    from mkdocs.structure.files import File

    for name, (words, _) in _commands().items():
        files.append(File.generated(config, f"reference/{name}.md", content=page(words)))
    return files
