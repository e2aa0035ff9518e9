"""Plant each mutation of tests/MUTATIONS.md (section arch) alone, run its fast tests, restore the source.

``python tests/plant_mutations.py [ID ...]`` prints KILLED or SURVIVED per mutation.
"""
import subprocess
import sys
import time
from pathlib import Path

ROOT = str(Path(__file__).resolve().parents[1]) + "/"
PYTHON = sys.executable
M = [
 # (id, file, old, new, tests)
 ("hammer-damper-sign", "coupling/cosim/linear_modes.py", "A[n + 1, n + 1] = -(side.ci + C) / m1", "A[n + 1, n + 1] = -(side.ci - C) / m1", "tests/test_hammer_boundary.py"),
 ("jacobi-order2-curvature", "coupling/cosim/exchange.py", "c[4 + k] = 2.0 * f012", "c[4 + k] = f012", "tests/test_cosim.py -k taylor"),
 ("energy-residual-half", "coupling/cosim/exchange.py", "xe = c[0] + c[2] * h + 0.5 * c[4] * h * h", "xe = c[0] + c[2] * h + c[4] * h * h", "tests/test_cosim.py -k energy_residual_is"),
 ("energy-residual-hammer-work", "coupling/cosim/exchange.py", "e_hammer = F_held * (x_new - wh[0, 0])", "e_hammer = F_held * x_new", "tests/test_cosim.py -k energy_residual_is"),
 ("held-force-order2-weight", "coupling/cosim/exchange.py", "w[2] = m2 * q / a2", "w[2] = -m2 * q / a2", "tests/test_cosim.py -k held_force_is"),
 ("gauss-seidel-order1-spacing", "coupling/cosim/exchange.py", "c[2 + k] = (wn - w0) / h", "c[2 + k] = (wn - w0) / a", "tests/test_cosim.py -k taylor"),
 ("held-force-order1", "coupling/cosim/exchange.py", "r = 0.5 * h / a", "r = h / a", "tests/test_cosim.py -k held_force_is"),
 ("gauss-seidel-order2-curvature", "coupling/cosim/exchange.py", "c[4 + k] = 2.0 * f3", "c[4 + k] = f3", "tests/test_cosim.py -k taylor"),
 ("recorder-wob-column", "coupling/cosim/recorder.py", '_OUT = {"wob": OUT_WOB,', '_OUT = {"wob": OUT_HAMMER_POSITION,', "tests/test_cosim.py -k 'energy_residual_of_the_steady or matches_monolithic'"),
 ("stability-blowup-sign", "coupling/cosim/stability.py", "if abs(F - self.W) > self.F_scale:", "if abs(F - self.W) < self.F_scale:", "tests/test_cosim.py -k energy_residual_of_the_steady"),
 ("regime-bounce-boundary", "fmu_src/regime.py", "bounce=groups.a >= groups.b", "bounce=groups.a > groups.b", "tests/test_model.py -k regime_flags"),
 ("regime-runaway-boundary", "fmu_src/regime.py", "runaway=groups.b > floor", "runaway=groups.b >= floor", "tests/test_model.py -k regime_flags"),
 ("regime-floor-without-decay", "fmu_src/regime.py", "floor = groups.mu if groups.gamma_hat > 0.0 else 1.0", "floor = groups.mu if groups.gamma_hat > 1e-6 else 1.0", "tests/test_model.py -k regime_flags"),
 ("status-event-storm-class", "fmu_src/solver_errors.py", "        raise EventStormError(", "        raise StepSizeError(", "tests/test_model.py -k event_storm"),
 ("status-log-full", "fmu_src/solver_errors.py", '    if status == ST_LOG_FULL:\n        return "log_full"', '    if status == ST_LOG_FULL:\n        return "done"', "tests/test_stepper.py -k full_event_log"),
 ("settings-typed-name", "fmu_src/settings.py", "raise e.renamed(typed.get(e.name, e.name)) from None", "raise e from None", "tests/test_model.py -k typed_name"),
 ("settings-si-alias", "fmu_src/settings.py", '"K": "stiffness",', '"K": "damping",', "tests/test_model.py -k 'si_overrides or typed_name'"),
 ("stepper-initial-stick-mode", "fmu_src/stepping.py", "ist[KL.I_STICK] = KL.SLIP if y[KL.V_BIT] > 0.0 else KL.STICK", "ist[KL.I_STICK] = KL.SLIP if y[KL.V_BIT] >= 0.0 else KL.STICK", "tests/test_model.py -k 'paper_fig9_period or slip_start'"),
 ("fmu-state-corrupt-status", "fmu_src/fmu_state.py", "_DESERIALIZED.status = FMI_ERROR", "_DESERIALIZED.status = FMI_OK", "tests/test_fmu_state.py"),
 ("fmu-state-format-check", "fmu_src/fmu_state.py", 'if not isinstance(s, dict) or s.get("format") != STATE_FORMAT:', 'if not isinstance(s, dict):', "tests/test_fmu_state.py"),
 ("fmu-solver-failure-status", "fmu_src/slave.py", "    def _fail(self, message: str, status: int = ERROR) -> bool:", "    def _fail(self, message: str, status: int = WARNING) -> bool:", "tests/test_fmu.py -k bad_do_step_in_process"),
 ("friction-taylor-curvature", "fmu_src/kernel_forces.py", "e = EXP_FRICTION_TAYLOR * (1.0 - u + 0.5 * u * u)", "e = EXP_FRICTION_TAYLOR * (1.0 - u + u * u)", "tests/test_kernel_units.py -k friction"),
 ("watch-slope-bounce-sign", "fmu_src/kernel_events.py", "return -s if kind == EV_BOUNCE else s", "return s", "tests/test_kernel_units.py -k slope"),
 ("watch-slope-clamp-sign", "fmu_src/kernel_events.py", "        return -p[P_LAM] * ddd\n", "        return p[P_LAM] * ddd\n", "tests/test_kernel_units.py -k slope"),
]
only = sys.argv[1:]
res = {}
for mid, f, old, new, tests in M:
    if only and mid not in only:
        continue
    path = ROOT + f
    src = open(path).read()
    assert src.count(old) == 1, (mid, src.count(old))
    open(path, "w").write(src.replace(old, new))
    t0 = time.time()
    try:
        r = subprocess.run(f"cd {ROOT} && timeout 1200 {PYTHON} -m pytest -q -n 0 -x -p no:cacheprovider {tests}",
                           shell=True, capture_output=True, text=True)
    finally:
        open(path, "w").write(src)
    tail = r.stdout.strip().splitlines()[-1] if r.stdout.strip() else r.stderr[-200:]
    killed = r.returncode == 1 and "failed" in tail
    res[mid] = (killed, tail, round(time.time() - t0))
    print(mid, "KILLED" if killed else "SURVIVED", tail, flush=True)
sys.exit(0 if all(k for k, _, _ in res.values()) else 1)
