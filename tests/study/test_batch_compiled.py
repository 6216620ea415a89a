"""The study batch's compiled tick (:mod:`davinci_sim.study.tick_kernel`) against its Python
tick (the batch laws, the oracle): the same trials give the same state tick by tick to
rounding, the same rows, the teleoperation handed to Python when a row needs it, and the
Python tick wherever a fixture has no compiled form."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.study import TrialSpec
from davinci_sim.study.batch import TrialBatch
from davinci_sim.study.batch_compiled import _KERNELS
from davinci_sim.study.report import COLUMNS, TIMING_COLUMNS

pytestmark = pytest.mark.skipif(_KERNELS is None, reason="needs numba")


def _specs(task: str, timeout: float = 60.0, fixture=None) -> list[TrialSpec]:
    return [
        TrialSpec(task, subject=s, condition=c, B=B, G_max=G, repetition=1, order=1,
                  practice=p, seed=5, timeout=timeout, **({"fixture": fixture} if fixture else {}))
        for s, c, B, G, p in ((0, 0, 0.0, 0.0, 1), (1, 3, 60.0, 8.0, 4), (1, 1, 20.0, 2.0, 7))
    ]  # fmt: skip


def _pair(specs) -> tuple[TrialBatch, TrialBatch]:
    compiled, python = TrialBatch(specs), TrialBatch(specs)
    assert compiled._compiled is not None
    python._compiled = None
    return compiled, python


#: Tick by tick the two differ by rounding only (the compiled rows sum the 3x3 and 4x4
#: products in index order, numpy's matmul in BLAS's): µm·1e-6 in positions after 1.5 s.
STATE = {"Q": 1e-11, "V": 1e-8, "q_ref": 1e-11, "T_psm": 1e-11, "T_mtm": 1e-11,
         "bias": 1e-9, "requested": 1e-7, "wrench_sent": 1e-7, "tau_ff": 1e-7}  # fmt: skip


def test_compiled_ticks_are_the_python_ticks(short_task):
    compiled, python = _pair(_specs(short_task, timeout=1.5))
    try:
        moved = 0.0
        while python.active.any():
            compiled.tick()
            python.tick()
            np.testing.assert_array_equal(compiled.active, python.active)
            np.testing.assert_array_equal(compiled.fault, python.fault)
            for name, atol in STATE.items():
                np.testing.assert_allclose(getattr(compiled, name), getattr(python, name),
                                           rtol=0, atol=atol, err_msg=name)  # fmt: skip
            np.testing.assert_allclose(compiled.jaw_sent, python.jaw_sent, rtol=0, atol=1e-12)
            moved = max(moved, float(np.abs(python.requested).max()))
        assert moved > 0.01  # (the guidance pushed: the haptic half of the tick was exercised)
        assert np.array_equal(compiled.state.phase, python.state.phase)
        # the signature the module's warm-up compiled at import is the one the ticks use
        from davinci_sim.devices import device_row  # (numba only)

        kernels = (_KERNELS.teleop_rows, _KERNELS.physics_rows, device_row.hand_rows)
        assert [len(k.signatures) for k in kernels] == [1, 1, 1]
    finally:
        compiled._setup.sim.close()
        python._setup.sim.close()


def test_whole_trials_give_the_python_ticks_rows(short_task):
    """Run to the end, with rows dropped as trials end: the rows agree (rounding-level
    differences in the state move a metric at most in its last digits)."""
    specs = _specs(short_task)
    rows = {}
    for label, compiled in (("compiled", True), ("python", False)):
        batch = TrialBatch(specs)
        if not compiled:
            batch._compiled = None
        try:
            rows[label] = batch.run()
        finally:
            batch._setup.sim.close()
    keys = [k for k in COLUMNS if k not in TIMING_COLUMNS]
    for a, b in zip(rows["compiled"], rows["python"], strict=True):
        assert a["finished"] and b["finished"]
        for k in keys:
            if isinstance(a[k], float):
                assert a[k] == pytest.approx(b[k], rel=1e-6, abs=1e-9), k
            else:
                assert a[k] == b[k], k


def test_a_row_needing_the_python_teleoperation_hands_the_tick_over(short_task, monkeypatch):
    """A singular PSM Jacobian has no compiled solve: that tick's teleoperation runs in
    Python for every row, and the tick goes on compiled."""
    compiled, python = _pair(_specs(short_task, timeout=0.2))
    handed = []
    teleop = TrialBatch._teleop

    def counting(self):
        if self._compiled is not None:
            handed.append(int(self.ticks.max()))
        teleop(self)

    monkeypatch.setattr(TrialBatch, "_teleop", counting)
    try:
        for k in range(60):
            if k in (10, 30):
                compiled.J_psm[1] = 0.0
                python.J_psm[1] = 0.0
            compiled.tick()
            python.tick()
            for name, atol in STATE.items():
                np.testing.assert_allclose(getattr(compiled, name), getattr(python, name),
                                           rtol=0, atol=atol, err_msg=name)  # fmt: skip
        assert handed == [10, 30]
    finally:
        compiled._setup.sim.close()
        python._setup.sim.close()


def _two_laws(path, **params):
    """A sum of two laws: no compiled form (the fixture row computes one law)."""
    from davinci_sim.haptics.combine import combine
    from davinci_sim.haptics.spring import SpringGuidance
    from davinci_sim.haptics.viscous import ViscousGuidance

    return combine(ViscousGuidance(path, B=20.0, G_max=2.0), SpringGuidance(path, stiffness=100.0))


def test_a_fixture_without_a_compiled_form_runs_the_python_tick(short_task):
    from davinci_sim.haptics.kinds import register_fixture_kind

    register_fixture_kind("two_laws_test", _two_laws, params=())
    batch = TrialBatch(_specs(short_task, timeout=0.1, fixture={"type": "two_laws_test"}))
    try:
        assert batch._compiled is None
        batch.run()
    finally:
        batch._setup.sim.close()


@pytest.mark.parametrize("fixture", [
    {"name": "spring", "type": "spring", "stiffness": 600.0, "damping": 4.0, "max_force": 3.0},
    {"name": "rota", "type": "viscous_elastic", "B": 15.0, "elastic_gain": 0.8,
     "threshold": 0.002, "half": 0.002, "slope": 500.0, "max_force": 3.0, "assistance": 0.5},
    {"name": "none", "type": "none"},
], ids=lambda f: f["name"])  # fmt: skip
def test_the_other_compiled_laws_tick_as_the_python_ticks(short_task, fixture):
    """A spring, Rota's viscous-elastic fixture and no fixture run the compiled tick
    (``fixture_law_row``'s laws); tick by tick within the rounding of the numpy tick."""
    compiled, python = _pair(_specs(short_task, timeout=1.0, fixture=fixture))
    try:
        from davinci_sim.haptics import fixture_row

        code = {"spring": fixture_row.SPRING, "viscous_elastic": fixture_row.VISCOUS_ELASTIC,
                "none": fixture_row.VISCOUS}[fixture["type"]]  # fmt: skip
        assert (compiled._compiled["law"] == code).all()
        while python.active.any():
            compiled.tick()
            python.tick()
            np.testing.assert_array_equal(compiled.active, python.active)
            for name, atol in STATE.items():
                np.testing.assert_allclose(getattr(compiled, name), getattr(python, name),
                                           rtol=0, atol=atol, err_msg=name)  # fmt: skip
        if fixture["type"] != "none":
            assert float(np.abs(python.requested).max()) > 0.01  # the fixture pushed
    finally:
        compiled._setup.sim.close()
        python._setup.sim.close()
