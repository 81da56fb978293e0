"""heliostep.sizing.pool: the sheet's speed-torque curves co-simulated in a pool of processes are the curves
co-simulated here one after another (the same bench simulations); a stop request ends the pool, the curves
under way kept."""

from __future__ import annotations

import numpy as np

from heliostep.scenario.catalogue import load_catalogue
from heliostep.sizing.pool import CurveTask, on_every_core

NAME = "QSH8618-65-59-340"  # currents 3, 4.5, 5.9 A


def _tasks() -> dict[str, CurveTask]:
    [candidate] = load_catalogue(None, [NAME])
    drive = candidate.drive()
    return {f"{current} A": CurveTask(drive, current, (50.0, 400.0), "one-phase-on", 1) for current in (3.0, 5.9)}


def test_the_curves_of_a_pool_are_those_co_simulated_one_after_another(fmu_paths):
    (here, stopped), (pooled, stopped_too) = on_every_core(_tasks(), workers=1), on_every_core(_tasks(), workers=2)
    assert not stopped and not stopped_too and here.keys() == pooled.keys()
    for key, curve in here.items():
        assert curve.holding_torque == pooled[key].holding_torque
        assert np.array_equal(curve.pull_out_torques, pooled[key].pull_out_torques)
    # the physics, not only the sameness: the larger current holds and pulls out more, and each falls with speed
    low, high = here["3.0 A"], here["5.9 A"]
    assert high.holding_torque > low.holding_torque and np.all(high.pull_out_torques > low.pull_out_torques)
    assert np.all(np.diff(high.pull_out_torques) < 0)


def test_a_stop_request_ends_the_pool_keeping_the_curves_under_way(fmu_paths):
    tasks = {k: task for k, task in enumerate(list(_tasks().values()) * 3)}  # six curves on two processes
    seen: list[int] = []  # the stop request comes once a curve is done: the other one under way finishes, kept
    done, stopped = on_every_core(tasks, lambda: bool(seen), workers=2, on_done=lambda k, v: seen.append(k))
    assert stopped and sorted(done) == sorted(seen) == [0, 1]
