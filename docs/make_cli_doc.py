"""The command reference of docs/cli.md, generated from the ``hammerbit`` parser.

    python docs/make_cli_doc.py            # print the reference
    python docs/make_cli_doc.py --update   # rewrite it in docs/cli.md (between the markers)

``tests/test_docs.py`` checks that docs/cli.md holds exactly what this script
generates, so the reference cannot drift from the code.
"""
from __future__ import annotations

import argparse
import pathlib
import sys

START = "<!-- cli-reference:start -->"
END = "<!-- cli-reference:end -->"
DOC = pathlib.Path(__file__).resolve().parent / "cli.md"


def _cell(text) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _option(action) -> str:
    names = ", ".join(f"`{s}`" for s in action.option_strings) or f"`{action.dest}`"
    if action.nargs == 0:
        return names
    mv = action.metavar
    if isinstance(mv, tuple):
        mv = " ".join(mv)
    elif mv is None:
        mv = "{" + ",".join(map(str, action.choices)) + "}" if action.choices else action.dest.upper()
    if action.nargs not in (None, 1) and not isinstance(action.metavar, tuple) and isinstance(action.nargs, int):
        mv = " ".join([mv] * action.nargs)
    return f"{names} `{mv}`"


def _default(action) -> str:
    d = action.default
    if action.nargs == 0 or d is None or d is argparse.SUPPRESS or d == [] or d is False:
        return "" if not action.required else "required"
    return f"`{' '.join(map(str, d)) if isinstance(d, (list, tuple)) else d}`"


def reference() -> str:
    """Markdown: every sub-command with its help and a table of its options."""
    from hammerbit.cli.main import build_parser
    ap = build_parser()
    sub = next(a for a in ap._actions if isinstance(a, argparse._SubParsersAction))
    lines = []
    _commands(sub, "hammerbit", lines)
    return "\n".join(lines).rstrip() + "\n"


def _commands(sub, prefix: str, lines: list) -> None:
    """The sections of every command of ``sub``, and of the commands nested in them (``fmu build``)."""
    helps = {c.dest: c.help for c in sub._choices_actions}
    for name, p in sub.choices.items():
        lines += [f"### `{prefix} {name}`", "", _cell(helps.get(name) or p.description or ""), ""]
        if p.description and p.description != helps.get(name):
            lines += [_cell(p.description), ""]
        nested = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        lines += ["| option | default | help |", "|---|---|---|"]
        for a in p._actions:
            if isinstance(a, argparse._HelpAction):
                continue
            req = "required" if a.required else _default(a)
            # argparse writes a percent sign as %% in help strings
            lines.append(f"| {_option(a)} | {req} | {_cell((a.help or '').replace('%%', '%'))} |")
        lines.append("")
        for a in nested:
            _commands(a, f"{prefix} {name}", lines)


def current(doc: pathlib.Path = DOC) -> str:
    """The reference as it stands in docs/cli.md."""
    text = doc.read_text(encoding="utf-8")
    i, j = text.index(START) + len(START), text.index(END)
    return text[i:j].strip("\n") + "\n"


def update(doc: pathlib.Path = DOC) -> bool:
    """Rewrite the reference in ``doc``; True if it changed."""
    text = doc.read_text(encoding="utf-8")
    i, j = text.index(START) + len(START), text.index(END)
    new = text[:i] + "\n" + reference() + text[j:]
    if new != text:
        doc.write_text(new, encoding="utf-8")
        return True
    return False


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--update", action="store_true", help="rewrite the reference in docs/cli.md")
    a = ap.parse_args(argv)
    if a.update:
        print("docs/cli.md " + ("updated" if update() else "already up to date"), file=sys.stderr)
    else:
        print(reference())
    return 0


if __name__ == "__main__":
    sys.exit(main())
