"""The compile cache of the FMU builds: hits give a fresh compile's bytes, every input change misses, a bad entry is rebuilt."""
from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from hammerbit.fmu import compile_cache
from hammerbit.fmu.compile_cache import SWITCH, cache_enabled, compile_key, compile_output
from hammerbit.fmu.guid import content_guid, replace_guid
from hammerbit.fmu.native import find_compiler

CC = shutil.which(os.environ.get("CC", "")) or shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler")

# __FILE__ of a header in the scratch directory: -ffile-prefix-map keeps its name out of the binary
SOURCE = '#include "tiny.h"\nconst char *where(void) { return HERE; }\nint value(void) { return VALUE; }\n'
HEADER = '#define VALUE 42\n#define HERE __FILE__\n'


def _scratch(parent: Path, name: str, source=SOURCE, header=HEADER) -> Path:
    """A build directory as the FMU builds make one: the source and a generated header in it."""
    d = parent / name
    (d / "gen").mkdir(parents=True)
    (d / "tiny.c").write_text(source)
    (d / "gen" / "tiny.h").write_text(header)
    return d


def _cmd(d: Path, cc=CC, flags=("-O2",)) -> list:
    return [cc, "-std=gnu11", *flags, "-fPIC", "-shared", f"-ffile-prefix-map={d}=.", "-I", str(d / "gen"),
            "-o", str(d / "tiny.so"), str(d / "tiny.c")]


def _compile(d: Path, monkeypatch, **kw) -> tuple:
    """(came from the cache, output bytes) of the tiny compile in ``d``."""
    hit = compile_output(_cmd(d, **kw), d / "tiny.so", scratch=(d,))
    return hit, (d / "tiny.so").read_bytes()


def _fresh(d: Path, monkeypatch, **kw) -> bytes:
    """The bytes of the compile with the cache off (the oracle)."""
    monkeypatch.setenv(SWITCH, "0")
    try:
        assert compile_output(_cmd(d, **kw), d / "tiny.so", scratch=(d,)) is False
    finally:
        monkeypatch.delenv(SWITCH)
    return (d / "tiny.so").read_bytes()


@pytest.fixture
def cache_root(tmp_path, monkeypatch):
    """An empty cache root of this test (the compile cache is a directory in it)."""
    root = tmp_path / "cache"
    monkeypatch.setenv("HAMMERBIT_CACHE_DIR", str(root))
    monkeypatch.delenv(SWITCH, raising=False)
    return root


def _entries(root: Path) -> list:
    return sorted(p for p in (root / compile_cache.CACHE_DIR_NAME).glob("*/*") if not p.name.endswith(".tmp"))


def test_a_hit_gives_the_bytes_of_a_fresh_compile_in_another_directory(cache_root, tmp_path, monkeypatch):
    first = _compile(_scratch(tmp_path, "a"), monkeypatch)
    again = _compile(_scratch(tmp_path, "b"), monkeypatch)
    oracle = _fresh(_scratch(tmp_path, "c"), monkeypatch)
    assert first[0] is False and again[0] is True
    # the oracle compiled in a third directory: the output does not depend on the scratch path
    assert again[1] == first[1] == oracle
    assert len(_entries(cache_root)) == 1
    assert os.access(tmp_path / "b" / "tiny.so", os.X_OK)     # the linker's permissions kept


@pytest.mark.parametrize("change", ["source", "header", "flag", "compiler"])
def test_a_changed_input_misses(change, cache_root, tmp_path, monkeypatch):
    _compile(_scratch(tmp_path, "a"), monkeypatch)
    kw, source, header = {}, SOURCE, HEADER
    if change == "source":
        source = SOURCE.replace("VALUE;", "VALUE + 1;")
    elif change == "header":
        header = HEADER.replace("42", "43")
    elif change == "flag":
        kw["flags"] = ("-O1",)
    else:
        wrapper = tmp_path / "bin" / "mycc"          # another compiler: a wrapper of this one
        wrapper.parent.mkdir()
        wrapper.write_text(f'#!/bin/sh\nexec {CC} "$@"\n')
        wrapper.chmod(0o755)
        kw["cc"] = str(wrapper)
    hit, got = _compile(_scratch(tmp_path, "b", source, header), monkeypatch, **kw)
    assert hit is False
    assert got == _fresh(_scratch(tmp_path, "c", source, header), monkeypatch, **kw)
    assert len(_entries(cache_root)) == 2


def test_a_header_anywhere_under_an_include_directory_is_in_the_key(tmp_path):
    a, b = _scratch(tmp_path, "a"), _scratch(tmp_path, "b")
    (b / "gen" / "sub").mkdir()
    (b / "gen" / "sub" / "other.h").write_text("#define OTHER 1\n")   # #include "sub/other.h" reads it
    assert compile_key(_cmd(a), a / "tiny.so", (a,)) != compile_key(_cmd(b), b / "tiny.so", (b,))
    (a / "gen" / "sub").mkdir()
    (a / "gen" / "sub" / "other.h").write_text("#define OTHER 1\n")
    assert compile_key(_cmd(a), a / "tiny.so", (a,)) == compile_key(_cmd(b), b / "tiny.so", (b,))


@pytest.mark.parametrize("damage", ["flip", "truncate", "empty"])
def test_a_corrupt_entry_is_rebuilt_and_replaced(damage, cache_root, tmp_path, monkeypatch):
    good = _compile(_scratch(tmp_path, "a"), monkeypatch)[1]
    (entry,) = _entries(cache_root)
    blob = bytearray(entry.read_bytes())
    if damage == "flip":
        blob[-100] ^= 0xFF                          # a byte of the binary
    elif damage == "truncate":
        blob = blob[:len(blob) // 2]
    else:
        blob = b""
    entry.write_bytes(bytes(blob))
    hit, got = _compile(_scratch(tmp_path, "b"), monkeypatch)
    assert hit is False and got == good
    assert _compile(_scratch(tmp_path, "c"), monkeypatch) == (True, good)   # replaced by a good one


def test_an_unusable_cache_directory_still_builds(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("HAMMERBIT_CACHE_DIR", str(blocker / "cache"))       # cannot be created
    monkeypatch.delenv(SWITCH, raising=False)
    oracle = _fresh(_scratch(tmp_path, "o"), monkeypatch)
    assert _compile(_scratch(tmp_path, "a"), monkeypatch) == (False, oracle)
    # a cache others can write to is not used: an entry planted there would be shipped
    shared = tmp_path / "shared"
    (shared / compile_cache.CACHE_DIR_NAME).mkdir(parents=True)
    (shared / compile_cache.CACHE_DIR_NAME).chmod(0o777)
    monkeypatch.setenv("HAMMERBIT_CACHE_DIR", str(shared))
    assert _compile(_scratch(tmp_path, "b"), monkeypatch) == (False, oracle)
    assert _compile(_scratch(tmp_path, "c"), monkeypatch) == (False, oracle)
    assert _entries(shared) == []


def test_the_switch_turns_the_cache_off_and_a_bad_value_is_refused(cache_root, tmp_path, monkeypatch):
    _fresh(_scratch(tmp_path, "a"), monkeypatch)
    assert _entries(cache_root) == []
    monkeypatch.setenv(SWITCH, "maybe")
    with pytest.raises(ValueError, match=f"{SWITCH} = 'maybe' is out of range"):
        cache_enabled()


def test_a_build_refuses_a_bad_switch_before_any_work(tmp_path, monkeypatch):
    from hammerbit.fmu.build import build_fmu
    monkeypatch.setenv(SWITCH, "maybe")
    with pytest.raises(ValueError, match=f"{SWITCH} = 'maybe'"):
        build_fmu(tmp_path / "x.fmu", runtime="native")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv", [["fmu", "build", "--runtime", "native"], ["fmu", "build-system", "--string", "lab"],
                                  ["ssp", "build", "--string", "lab"]])
def test_the_commands_that_build_refuse_a_bad_switch_with_exit_2(argv, tmp_path, monkeypatch, capsys):
    from hammerbit.cli.main import main
    monkeypatch.setenv(SWITCH, "maybe")
    monkeypatch.chdir(tmp_path)
    assert main([*argv, "--out", str(tmp_path / ("x.ssp" if argv[0] == "ssp" else "x.fmu"))]) == 2
    err = capsys.readouterr().err
    assert f"{SWITCH} = 'maybe' is out of range" in err and "Traceback" not in err and "building" not in err
    assert list(tmp_path.iterdir()) == []


def test_the_oldest_entries_are_pruned(cache_root, tmp_path, monkeypatch):
    monkeypatch.setattr(compile_cache, "MAX_ENTRIES", 2)
    for k in range(3):
        d = _scratch(tmp_path, f"s{k}", header=HEADER.replace("42", str(k)))
        _compile(d, monkeypatch)
        entries = _entries(cache_root)
        os.utime(max(entries, key=lambda p: p.stat().st_mtime_ns), ns=(k * 10 ** 9, k * 10 ** 9))
    assert len(_entries(cache_root)) == 2
    # the first (oldest) is gone: compiling it again misses, the newest still hits
    assert _compile(_scratch(tmp_path, "again0", header=HEADER.replace("42", "0")), monkeypatch)[0] is False
    assert _compile(_scratch(tmp_path, "again2", header=HEADER.replace("42", "2")), monkeypatch)[0] is True


_CONCURRENT = """
import sys
from pathlib import Path
from hammerbit.fmu.compile_cache import compile_output
d = Path(sys.argv[1])
cmd = [sys.argv[2], "-std=gnu11", "-O2", "-fPIC", "-shared", f"-ffile-prefix-map={d}=.", "-I", str(d / "gen"),
       "-o", str(d / "tiny.so"), str(d / "tiny.c")]
compile_output(cmd, d / "tiny.so", scratch=(d,))
"""


def test_two_processes_on_one_key_both_get_the_right_bytes(cache_root, tmp_path, monkeypatch):
    oracle = _fresh(_scratch(tmp_path, "o"), monkeypatch)
    dirs = [_scratch(tmp_path, f"p{k}") for k in range(2)]
    procs = [subprocess.Popen([sys.executable, "-c", _CONCURRENT, str(d), CC], stderr=subprocess.PIPE)
             for d in dirs]
    for p in procs:
        assert p.wait(timeout=120) == 0, p.stderr.read().decode()
    for d in dirs:
        assert (d / "tiny.so").read_bytes() == oracle
    assert _compile(_scratch(tmp_path, "after"), monkeypatch) == (True, oracle)
    assert len(_entries(cache_root)) == 1


def test_a_missing_compiler_is_reported_not_hidden_by_the_cache(cache_root, tmp_path):
    d = _scratch(tmp_path, "a")
    with pytest.raises(RuntimeError, match="cannot run"):
        compile_output(_cmd(d, cc=str(tmp_path / "no-such-cc")), d / "tiny.so", scratch=(d,))


def test_the_guid_is_a_fingerprint_of_the_description_and_the_code():
    md = (b'<?xml version="1.0"?>\n<fmiModelDescription fmiVersion="2.0" modelName="M" guid="x" '
          b'generationDateAndTime="2026-01-01T00:00:00Z"><ModelVariables/></fmiModelDescription>')
    later = md.replace(b"2026-01-01", b"2027-02-02").replace(b'guid="x"', b'guid="y"')
    assert content_guid(md, "c1") == content_guid(later, "c1")          # time and old GUID left out
    assert content_guid(md, "c1") != content_guid(md, "c2")
    assert content_guid(md, "c1") != content_guid(md.replace(b'"M"', b'"N"'), "c1")
    assert replace_guid(md, "G") == md.replace(b'guid="x"', b'guid="G"')


def _members(fmu: Path) -> dict:
    with zipfile.ZipFile(fmu) as zf:
        return {n: zf.read(n) for n in zf.namelist()}


def test_a_native_fmu_from_a_warm_cache_is_the_fmu_built_without_it(built_fmu, tmp_path, monkeypatch):
    """One real build: every compiler run of the native flavour from the cache, byte for byte the
    binaries and description of a build with the cache off (made in another temporary directory)."""
    find_compiler()
    from hammerbit.fmu import native_build
    from hammerbit.fmu.native_build import assemble_native_fmu
    hits = []

    def spy(*args, **kw):
        hits.append(compile_output(*args, **kw))
        return hits[-1]

    monkeypatch.setattr(native_build, "compile_output", spy)
    start = {"preload": 35.0}
    assemble_native_fmu(built_fmu, tmp_path / "fill.fmu", start, log=lambda *a: None)
    hits.clear()
    warm = _members(assemble_native_fmu(built_fmu, tmp_path / "warm.fmu", start, log=lambda *a: None))
    assert hits and all(hits)
    monkeypatch.setenv(SWITCH, "0")
    hits.clear()
    cold = _members(assemble_native_fmu(built_fmu, tmp_path / "cold.fmu", start, log=lambda *a: None))
    assert hits and not any(hits)
    assert sorted(warm) == sorted(cold)
    binaries = [n for n in cold if n.startswith("binaries/")]
    assert binaries and "modelDescription.xml" in cold
    for name in cold:
        assert warm[name] == cold[name], name
    mode = stat.S_IMODE(zipfile.ZipFile(tmp_path / "warm.fmu").getinfo(binaries[0]).external_attr >> 16)
    assert mode == stat.S_IMODE(zipfile.ZipFile(tmp_path / "cold.fmu").getinfo(binaries[0]).external_attr >> 16)
