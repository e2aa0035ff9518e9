"""The environment of a process that starts as a new user would: no kernel cache it may create or
reuse, no CPU target chosen for it."""
from __future__ import annotations

import os
from pathlib import Path

#: variables that would point a process at a cache or a CPU target chosen elsewhere
CACHE_AND_TARGET_VARS = ("HAMMERBIT_CACHE_DIR", "XDG_CACHE_HOME", "NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES",
                         "NUMBA_CACHE_DIR")


def cold_env(tmp_path: Path, **extra) -> dict:
    """This process's environment with HOME a file (no cache can be created below it, even as
    root), TMPDIR a fresh directory and the variables above dropped; ``extra`` set on top."""
    home = tmp_path / "home-is-a-file"
    home.write_text("")
    tmp = tmp_path / "tmp"
    tmp.mkdir(exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k not in CACHE_AND_TARGET_VARS}
    env.update(HOME=str(home), TMPDIR=str(tmp), **extra)
    return env
