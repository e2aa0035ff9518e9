"""The host's instances of one FMU file share one extraction directory (hammerbit.fmu.host).

Oracles: a lone instance's run (the bits a shared directory must not change), the directories on
disk, and a fresh process's exit."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys

import pytest

#: steps of each run [s]
STEP, STEPS = 0.01, 40
OUTPUTS = ("hammer_position", "hammer_velocity", "bit_position", "bit_velocity")


def _run(inst, preload):
    inst.set(preload=preload)
    rows = []
    for _ in range(STEPS):
        inst.step(STEP)
        rows.append(inst.get(*OUTPUTS))
    return rows


def test_instances_of_one_file_share_its_extraction_and_stay_independent(any_fmu):
    """Two instances on one directory, stepped in turns with other inputs, each end as a lone
    instance of the same inputs does, to the bit."""
    from hammerbit.fmu.host import FMUInstance
    with FMUInstance(any_fmu, "lone") as lone:
        preload = lone.get("preload")[0]
        alone = _run(lone, preload)
    a, b = FMUInstance(any_fmu, "a"), FMUInstance(any_fmu, "b")
    try:
        assert a.dir == b.dir == lone.dir and os.path.isdir(a.dir)
        a.set(preload=preload)
        b.set(preload=1.5 * preload)
        rows_a, rows_b = [], []
        for _ in range(STEPS):
            a.step(STEP)
            b.step(STEP)
            rows_a.append(a.get(*OUTPUTS))
            rows_b.append(b.get(*OUTPUTS))
        assert rows_a == alone
        assert rows_b != alone                 # b's input reached b only
        b.close()
        a.step(STEP)                           # closing b leaves a's directory and library in place
        assert not a.errors()
    finally:
        a.close()
        b.close()
    assert os.path.isdir(a.dir)                # kept for the next instance


def test_each_file_version_has_its_extraction_and_unused_ones_are_bounded(built_native_fmu, tmp_path,
                                                                          monkeypatch):
    from hammerbit.fmu import host
    monkeypatch.setattr(host, "UNUSED_EXTRACTIONS_KEPT", 2)
    paths = [tmp_path / f"v{i}.fmu" for i in range(5)]
    for p in paths:
        shutil.copyfile(built_native_fmu, p)
    held = host.FMUInstance(paths[0], "held")
    try:
        dirs = []
        for p in paths[1:]:
            with host.FMUInstance(p, "once") as inst:
                dirs.append(inst.dir)
        assert len(set(dirs + [held.dir])) == 5
        # the two most recently used directories no instance uses stay; the one in use stays
        assert [os.path.isdir(d) for d in dirs] == [False, False, True, True]
        assert os.path.isdir(held.dir)
        with host.FMUInstance(paths[3], "again") as inst:
            assert inst.dir == dirs[2]          # the same version: its kept directory, now the latest used
        st = os.stat(paths[4])
        os.utime(paths[4], ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))   # rebuilt in place
        with host.FMUInstance(paths[4], "rebuilt") as inst:
            assert inst.dir not in dirs
        # the old version of paths[4] was the least recently used
        assert [os.path.isdir(d) for d in dirs] == [False, False, True, False]
    finally:
        held.close()


def test_an_instance_that_fails_to_instantiate_gives_its_directory_back(built_native_fmu, tmp_path,
                                                                        monkeypatch):
    from hammerbit.fmu import host
    path = tmp_path / "HammerBitRock.fmu"
    shutil.copyfile(built_native_fmu, path)

    def refuse(self, name, logging):
        raise RuntimeError("fmi2Instantiate failed")
    monkeypatch.setattr(host.FMUInstance, "_instantiate", refuse)
    for _ in range(3):
        with pytest.raises(RuntimeError, match="fmi2Instantiate failed"):
            host.FMUInstance(path, "refused")
    users = [entry[1] for key, entry in host._EXTRACTIONS.items() if key[0] == os.path.realpath(path)]
    assert users == [0]


def test_the_extractions_are_removed_when_the_process_exits(built_native_fmu):
    """Even of an instance left open."""
    script = ("import sys\nfrom hammerbit.fmu.host import FMUInstance\n"
              "a = FMUInstance(sys.argv[1], 'open')\nb = FMUInstance(sys.argv[1], 'closed')\nb.close()\n"
              "a.step(0.01)\nprint(a.dir)\n")
    r = subprocess.run([sys.executable, "-c", script, str(built_native_fmu)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    directory = r.stdout.strip().splitlines()[-1]
    assert directory and not os.path.exists(directory)
