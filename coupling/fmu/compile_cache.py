"""A content-addressed cache of C compiler outputs (like ccache), through which every FMU build compiles.

Every compiler run of an FMU build (the native binaries of each platform, the
pythonfmu flavour's native front) goes through :func:`compile_output`.  It
computes a key from every byte that can change the output, and when the cache
holds an entry for the key it copies that entry to the output instead of
compiling; otherwise it compiles and stores the output under the key.

The key covers:

- the compiler: its resolved path, its ``--version`` output, its ``-v``
  configuration and search directories (include, programs, libraries) with the
  name, size and modification time of every file directly in each, so that a
  toolchain upgrade misses (memoised per process);
- the argument list, with the build's scratch directories (its temporary
  directories, different in every build) replaced by placeholders and the output
  by its file name only;
- the contents of every file named on the command line (sources, objects,
  libraries, ``-Wl,`` files) and of every file under every directory named on it
  (``-I``/``-L`` trees: the generated headers live in the scratch directory);
- the environment variables that change what the compiler does (:data:`COMPILER_ENVIRONMENT`),
  and the working directory when an argument is a relative path.

Normalising the scratch directories is honest only if the output does not depend
on where the scratch directory is: the builds make sure of it (no debug
information, ``-ffile-prefix-map`` of the scratch directory, a fixed image base
and no timestamp in the Windows DLLs), and the tests build the same inputs in
two directories and compare the bytes.

Entries live in ``compiler-outputs/`` under hammerbit's cache root (the numba
cache's root: ``$HAMMERBIT_CACHE_DIR``, else ``$XDG_CACHE_HOME/hammerbit/numba``),
each a file written atomically (temporary file and rename) holding the SHA-256
of its payload, which every read checks: a corrupt or truncated entry is
ignored, compiled again and replaced.  The newest :data:`MAX_ENTRIES` entries
and at most :data:`MAX_BYTES` are kept, the least recently used pruned first.
A cache directory that cannot be created or written, or that other users could
write to (a planted entry would be shipped), means compiling without the cache,
never a failed build.  ``HAMMERBIT_BUILD_CACHE=0`` turns the cache off.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import stat
import subprocess
import tempfile
from pathlib import Path

__all__ = ["SWITCH", "CACHE_DIR_NAME", "MAX_ENTRIES", "MAX_BYTES", "COMPILER_ENVIRONMENT",
           "cache_enabled", "cache_dir", "compiler_identity", "compile_key", "compile_output"]

#: the environment variable that turns the cache off (0) or on (1, the default)
SWITCH = "HAMMERBIT_BUILD_CACHE"
_OFF, _ON = ("0", "off", "no", "false"), ("", "1", "on", "yes", "true")
#: the cache's directory under hammerbit's cache root
CACHE_DIR_NAME = "compiler-outputs"
#: the cache keeps at most this many entries ...
MAX_ENTRIES = 400
#: ... and at most this many bytes (a native binary is 0.1-1 MB), the least recently used pruned
MAX_BYTES = 256 * 2 ** 20
#: environment variables that change what gcc, clang or the linker do (their values enter the key)
COMPILER_ENVIRONMENT = ("CPATH", "C_INCLUDE_PATH", "CPLUS_INCLUDE_PATH", "OBJC_INCLUDE_PATH",
                        "LIBRARY_PATH", "COMPILER_PATH", "GCC_EXEC_PREFIX", "GCC_COMPARE_DEBUG",
                        "SOURCE_DATE_EPOCH", "LD_RUN_PATH", "LD_LIBRARY_PATH", "DEPENDENCIES_OUTPUT",
                        "SUNPRO_DEPENDENCIES", "CCC_OVERRIDE_OPTIONS", "SDKROOT")
#: the programs the compiler driver runs that it may find on PATH (their identity enters the key)
_DRIVEN_PROGRAMS = ("as", "ld")
#: first line of an entry (a format change makes old entries unreadable, hence misses)
_MAGIC = b"hammerbit compiler output 1\n"
_DIGEST_LEN = 64
#: directories skipped in a tree named on the command line: Python's byte code, which no C
#: compile reads and which Python writes or not depending on its settings
_SKIPPED_DIRS = ("__pycache__",)


def cache_enabled() -> bool:
    """False when ``HAMMERBIT_BUILD_CACHE`` turns the cache off; a value that is neither on nor
    off raises ValueError naming it."""
    value = os.environ.get(SWITCH, "").strip().lower()
    if value in _OFF:
        return False
    if value in _ON:
        return True
    raise ValueError(f"{SWITCH} = {os.environ[SWITCH]!r} is out of range: allowed 0 (the build cache "
                     f"off) or 1 (on, the default)")


def cache_dir(name: str = CACHE_DIR_NAME):
    """The cache's directory (``name`` under the cache root), created if need be; None when it
    cannot be used (not writable, or writable by other users, whose entries would be shipped in the
    FMUs)."""
    from hammerbit.model.numba_cache_place import untrusted, user_cache_root
    root = Path(user_cache_root())
    path = root / name
    try:
        path.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError:
        return None
    if untrusted(str(path)) is not None or not os.access(path, os.W_OK | os.X_OK):
        return None
    return path


# ---------------------------------------------------------------------------
# the key
# ---------------------------------------------------------------------------
_IDENTITIES: dict = {}


def _listing(directory: str) -> bytes:
    """Name, size and modification time of every file directly in ``directory`` (empty if absent)."""
    rows = []
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return b""
    for entry in entries:
        try:
            st = entry.stat()
        except OSError:
            continue                       # a dangling link: the compiler cannot read it either
        rows.append(f"{entry.name}\0{st.st_size}\0{st.st_mtime_ns}")
    return "\n".join(sorted(rows)).encode()


def _search_dirs(verbose: str) -> list:
    """The include, program and library directories of a compiler's ``-v`` output."""
    dirs, in_list = [], False
    for line in verbose.splitlines():
        if line.startswith("#include <...> search starts here:"):
            in_list = True
        elif line.startswith("End of search list."):
            in_list = False
        elif in_list and line.startswith(" "):
            dirs.append(line.strip())
        elif line.startswith(("COMPILER_PATH=", "LIBRARY_PATH=")):
            dirs += [d for d in line.split("=", 1)[1].split(":") if d]
    return sorted({os.path.normpath(d) for d in dirs})


def compiler_identity(cc: str) -> bytes:
    """What identifies the compiler ``cc`` and its toolchain (memoised per process): its resolved
    path, ``--version``, ``-v`` configuration, and the files of its search directories."""
    resolved = shutil.which(cc) or cc
    real = os.path.realpath(resolved)
    st = os.stat(real)
    memo = (real, st.st_size, st.st_mtime_ns)      # a compiler replaced in place is a new one
    if memo in _IDENTITIES:
        return _IDENTITIES[memo]
    version = subprocess.run([resolved, "--version"], capture_output=True, text=True)
    verbose = subprocess.run([resolved, "-v", "-E", "-x", "c", os.devnull, "-o", os.devnull],
                             capture_output=True, text=True)
    h = hashlib.sha256(f"{real}\0{st.st_size}\0{st.st_mtime_ns}\0".encode())
    h.update(version.stdout.encode() + b"\0" + verbose.stderr.encode() + b"\0")
    for d in _search_dirs(verbose.stderr):
        h.update(d.encode() + b"\0" + _listing(d) + b"\0")
    for prog in _DRIVEN_PROGRAMS:
        # the driver runs its own copy if it has one, else the first on PATH
        name = subprocess.run([resolved, f"-print-prog-name={prog}"], capture_output=True,
                              text=True).stdout.strip() or prog
        found = name if os.path.isabs(name) else shutil.which(name)
        if found:
            pst = os.stat(found)
            h.update(f"{prog}\0{os.path.realpath(found)}\0{pst.st_size}\0{pst.st_mtime_ns}\0".encode())
    _IDENTITIES[memo] = h.digest()
    return _IDENTITIES[memo]


def _candidates(arg: str) -> list:
    """The strings in one argument that may name a file or directory: the argument, the value of
    a joined option (``-I<dir>``, ``--opt=<file>``), each piece of ``-Wl,a,b``, ``@<file>``."""
    pieces = arg.split(",")[1:] if arg.startswith(("-Wl,", "-Wa,", "-Wp,")) else [arg]
    out = []
    for p in pieces:
        out.append(p)
        if "=" in p:
            out.append(p.split("=", 1)[1])
        for prefix in ("-isystem", "-iquote", "-idirafter", "-include", "-I", "-L", "@"):
            if p.startswith(prefix) and len(p) > len(prefix):
                out.append(p[len(prefix):])
                break
    return out


def _hash_tree(h, label: str, path: Path, normalise) -> None:
    """Every file under ``path`` (or the file itself): its name relative to the argument and bytes."""
    if path.is_file():
        h.update(f"file\0{label}\0".encode() + hashlib.sha256(path.read_bytes()).digest())
        return
    for root, dirs, files in os.walk(path):
        dirs[:] = sorted(d for d in dirs if d not in _SKIPPED_DIRS)
        for name in sorted(files):
            f = Path(root) / name
            if f.is_file():
                rel = normalise(str(f))
                h.update(f"tree\0{label}\0{rel}\0".encode() + hashlib.sha256(f.read_bytes()).digest())


def compile_key(cmd, output, scratch=()) -> str:
    """The cache key (hex SHA-256) of running ``cmd``, which writes ``output``; the directories
    ``scratch`` (the build's temporary directories) enter it by placeholder, not by name."""
    output = str(output)
    places = {}
    for i, d in enumerate(scratch):
        for form in (str(d), os.path.realpath(d)):
            places[form.rstrip(os.sep)] = f"<scratch{i}>"
    order = sorted(places, key=len, reverse=True)

    def normalise(s: str) -> str:
        for form in order:
            s = s.replace(form, places[form])
        return s

    h = hashlib.sha256(compiler_identity(cmd[0]))
    relative = False
    for arg in cmd[1:]:
        arg = str(arg)
        if arg == output:
            h.update(f"output\0{os.path.basename(output)}\0".encode())
            continue
        h.update(b"arg\0" + normalise(arg).encode() + b"\0")
        for cand in _candidates(arg):
            if cand and cand != output and os.path.exists(cand):
                relative |= not os.path.isabs(cand)
                _hash_tree(h, normalise(cand), Path(cand), normalise)
    for name in COMPILER_ENVIRONMENT:
        if name in os.environ:
            h.update(f"env\0{name}\0{normalise(os.environ[name])}\0".encode())
    if relative:
        h.update(f"cwd\0{normalise(os.getcwd())}\0".encode())
    return h.hexdigest()


# ---------------------------------------------------------------------------
# entries
# ---------------------------------------------------------------------------
def _read_entry(entry: Path):
    """``(mode, payload)`` of ``entry`` if its digest checks (None if absent, truncated or corrupt)."""
    try:
        blob = entry.read_bytes()
    except OSError:
        return None
    head = len(_MAGIC) + _DIGEST_LEN + 1
    if len(blob) < head or not blob.startswith(_MAGIC):
        return None
    body = blob[head:]
    if hashlib.sha256(body).hexdigest().encode() != blob[len(_MAGIC):head - 1]:
        return None
    mode, _, payload = body.partition(b"\n")
    return int(mode, 8), payload


def _write_atomic(path: Path, data: bytes, mode: int = 0o600) -> None:
    """Write ``data`` to ``path`` through a temporary file in its directory and a rename, so that
    a reader (another build) sees the old file or the whole new one."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _store(entry: Path, output: Path) -> None:
    """Store the compiler's ``output`` (bytes and permissions) as ``entry`` (silently nothing if
    the cache cannot be written)."""
    body = f"{stat.S_IMODE(output.stat().st_mode):o}\n".encode() + output.read_bytes()
    try:
        entry.parent.mkdir(mode=0o700, exist_ok=True)
        _write_atomic(entry, _MAGIC + hashlib.sha256(body).hexdigest().encode() + b"\n" + body)
    except OSError:
        return
    _prune(entry.parent.parent)


def _prune(root: Path) -> None:
    """Delete the least recently used entries beyond :data:`MAX_ENTRIES` or :data:`MAX_BYTES`
    (a concurrent build may delete the same ones: errors are ignored)."""
    entries = []
    for f in root.glob("*/*"):
        if f.name.endswith(".tmp"):
            continue                        # being written by a build
        try:
            st = f.stat()
        except OSError:
            continue
        entries.append((st.st_mtime_ns, st.st_size, f))
    entries.sort(reverse=True)
    total = 0
    for k, (_, size, f) in enumerate(entries):
        total += size
        if k >= MAX_ENTRIES or total > MAX_BYTES:
            try:
                f.unlink()
            except OSError:
                pass


def _run(cmd, what: str, error) -> None:
    try:
        r = subprocess.run(cmd, capture_output=True, text=True)
    except OSError as e:
        raise error(f"{what}: cannot run {cmd[0]}: {e}") from None
    if r.returncode != 0:
        raise error(f"{what} failed ({' '.join(map(str, cmd))}):\n{r.stderr.strip()[-4000:]}")


def compile_output(cmd, output, *, scratch=(), what: str = "compiling", error=RuntimeError) -> bool:
    """Make ``output`` as running the compiler command ``cmd`` would (``cmd`` names ``output``
    after ``-o``); True if it came from the cache.

    ``scratch``: the build's temporary directories, whose names change from build to build
    but not the output.  A failing compiler raises ``error`` with ``what`` and its messages."""
    cmd = [str(c) for c in cmd]
    output = Path(output)
    if str(output) not in cmd:
        raise ValueError(f"the compiler command does not write its output {output}")
    root = cache_dir() if cache_enabled() else None
    if root is None:
        _run(cmd, what, error)
        return False
    try:
        key = compile_key(cmd, output, scratch)
    except OSError:
        # an input or the compiler cannot be read: the compiler reports it better than a key could
        _run(cmd, what, error)
        return False
    entry = root / key[:2] / key[2:]
    found = _read_entry(entry)
    if found is not None:
        _write_atomic(output, found[1], found[0])
        try:
            os.utime(entry)                 # recently used: pruned last
        except OSError:
            pass
        return True
    _run(cmd, what, error)
    _store(entry, output)
    return False
