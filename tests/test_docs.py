"""The documentation is true to the code.

* Every fenced ```python block of README.md and docs/*.md runs (the blocks of
  one file in order, in one namespace, in a temporary directory that holds
  ``dist/HammerBitRock.fmu`` when the file uses the FMU). A block that cannot
  run in a test says so with ``<!-- doc-test: skip REASON -->`` on the line
  before its fence; :data:`MAX_SKIPPED` keeps that list short.
* docs/cli.md's command reference is what the parser generates.
* Links stay inside the repository and point at files that exist.
* No first-person or process wording.
"""
from __future__ import annotations

import importlib.util
import os
import pathlib
import re
import shutil

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
SKIP = re.compile(r"<!--\s*doc-test:\s*skip\b(.*?)-->")
FENCE = re.compile(r"^```(\w*)\s*$")
#: At most this many skipped blocks over all documents.
MAX_SKIPPED = 3


def code_blocks(path: pathlib.Path, lang: str = "python"):
    """``[(line, code, skip_reason or None)]`` of the fenced blocks of ``lang`` in a Markdown file."""
    out = []
    lines = path.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m and m.group(1):
            start, body = i + 1, []
            i += 1
            while i < len(lines) and not lines[i].startswith("```"):
                body.append(lines[i])
                i += 1
            if m.group(1) == lang:
                prev = next((lines[k] for k in range(start - 2, -1, -1) if lines[k].strip()), "")
                s = SKIP.search(prev)
                out.append((start + 1, "\n".join(body) + "\n", s.group(1).strip() or "no reason" if s else None))
        i += 1
    return out


def _ids(paths):
    return [str(p.relative_to(ROOT)) for p in paths]


def test_code_block_parser():
    """The block finder on a made-up document (so a silent parser bug cannot pass every doc)."""
    import tempfile
    text = ("# t\n\n```python\nx = 1\n```\n\n<!-- doc-test: skip needs a licence -->\n```python\ny = 2\n```\n"
            "```bash\nhammerbit simulate\n```\n```python\nassert x == 1\n```\n")
    with tempfile.TemporaryDirectory() as d:
        p = pathlib.Path(d) / "t.md"
        p.write_text(text)
        blocks = code_blocks(p)
    assert [b[1] for b in blocks] == ["x = 1\n", "y = 2\n", "assert x == 1\n"]
    assert [b[2] for b in blocks] == [None, "needs a licence", None]
    assert blocks[0][0] == 4


@pytest.mark.parametrize("doc", [p for p in DOCS if code_blocks(p)], ids=_ids([p for p in DOCS if code_blocks(p)]))
def test_python_blocks_run(doc, tmp_path, monkeypatch, request):
    blocks = code_blocks(doc)
    text = doc.read_text(encoding="utf-8")
    if any("HammerBitRock.fmu" in code for _, code, skip in blocks if not skip):
        fmu = request.getfixturevalue("built_fmu")
        (tmp_path / "dist").mkdir()
        shutil.copy(fmu, tmp_path / "dist" / "HammerBitRock.fmu")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    ns = {"__name__": "__doc_test__"}
    ran = 0
    for line, code, skip in blocks:
        if skip:
            continue
        try:
            exec(compile(code, f"{doc.name}:{line}", "exec"), ns)
        except Exception as e:  # noqa: BLE001 -- report which block failed
            pytest.fail(f"{doc.relative_to(ROOT)}, block at line {line}: {type(e).__name__}: {e}")
        ran += 1
    assert ran > 0 or "```python" not in text


def test_few_blocks_are_skipped():
    skipped = [(p.name, line, why) for p in DOCS for line, _, why in code_blocks(p) if why]
    assert len(skipped) <= MAX_SKIPPED, skipped


def _load_cli_doc():
    spec = importlib.util.spec_from_file_location("make_cli_doc", ROOT / "docs" / "make_cli_doc.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_cli_reference_is_current():
    mod = _load_cli_doc()
    assert mod.current() == mod.reference(), "docs/cli.md is stale: run python docs/make_cli_doc.py --update"


def test_cli_reference_lists_every_command_and_option():
    """Independent of the generator: every sub-command and option string of the parser appears in cli.md."""
    import argparse
    from hammerbit.cli.main import build_parser
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    ap = build_parser()
    sub = next(a for a in ap._actions if isinstance(a, argparse._SubParsersAction))
    for name, p in sub.choices.items():
        assert f"### `hammerbit {name}`" in text, name
        for a in p._actions:
            for opt in a.option_strings:
                if opt not in ("-h", "--help"):
                    assert f"`{opt}`" in text, (name, opt)


def test_exit_code_table_matches_the_code():
    from hammerbit.cli import common as c
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    rows = dict(re.findall(r"^\| (\d+) \| (.+?) \|$", text, flags=re.M))
    codes = {c.EXIT_OK, c.EXIT_FAILURE, c.EXIT_BAD_INPUT, c.EXIT_UNSTABLE, c.EXIT_CHECK_FAILED,
             c.EXIT_INACCURATE, c.EXIT_INFEASIBLE, c.EXIT_INTERRUPTED}
    assert {int(k) for k in rows} == codes
    assert "bad input" in rows[str(c.EXIT_BAD_INPUT)]
    assert "unstable" in rows[str(c.EXIT_UNSTABLE)]
    assert "check --strict" in rows[str(c.EXIT_CHECK_FAILED)]
    assert "no feasible" in rows[str(c.EXIT_INFEASIBLE)]


LINK = re.compile(r"\]\(([^)\s]+)\)")


@pytest.mark.parametrize("doc", DOCS, ids=_ids(DOCS))
def test_links_stay_in_the_repository(doc):
    text = doc.read_text(encoding="utf-8")
    assert "shared/spec" not in text and "../shared" not in text
    for target in LINK.findall(text):
        if re.match(r"^[a-z]+://", target) or target.startswith("#") or target.startswith("mailto:"):
            continue
        path = (doc.parent / target.split("#")[0]).resolve()
        assert str(path).startswith(str(ROOT)), f"{doc.name}: link outside the repository: {target}"
        assert path.exists(), f"{doc.name}: broken link {target}"


#: First-person and process wording that has no place in user documentation.
WORDING = [r"\bso I\b", r"\bI searched\b", r"\bI (found|ran|measured|tried|think)\b", r"\(issue \d+\)",
           r"\bissue \d+\b", r"done criterion", r"one-off observation"]


@pytest.mark.parametrize("doc", DOCS, ids=_ids(DOCS))
def test_no_first_person_or_process_wording(doc):
    text = doc.read_text(encoding="utf-8")
    found = [m.group(0) for w in WORDING for m in re.finditer(w, text, flags=re.I)]
    assert not found, f"{doc.name}: {found}"


def test_model_doc_defines_every_group_and_the_validity_domain():
    """docs/model.md names each group of the code with its definition, and the three regime flags."""
    from hammerbit.model.params import GROUP_NAMES
    from hammerbit.model.regime import Regime
    text = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    for g in GROUP_NAMES:
        assert re.search(rf"^\| `{g}` \|", text, flags=re.M), g
    for flag in Regime.__dataclass_fields__:
        assert f"**{flag}" in text, flag
    assert "x0" in text and "Omega" in text
