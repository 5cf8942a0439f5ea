"""Snapshots as state: any controller state round-trips through the snapshot codec and
runs on bit for bit as the original (``scan/statecodec.py``, ``kernel/capture.py``).

Generic on purpose: the scenario below starts a process of every kind the kernel and the
instructions define, a snapshot is taken after every step, and each copy runs the rest of
the script beside the original: the same values, cycle by cycle. A test at the end fails
when a process class exists that the scenario never captured (a new one: add a step that
starts it). A hypothesis test does the same with random scripts of every instruction type.
"""

from __future__ import annotations

import importlib
import io
import pickle
import pkgutil
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import motion_server.instructions as instructions_pkg
import motion_server.kernel as kernel_pkg
from motion_server import config
from motion_server.instructions import MotionSystem
from motion_server.kernel.processes import Process
from motion_server.scan import statecodec

from .test_properties import POWER_UP, Step, scripts
from .test_properties import build as build_four_axes

S_CURVE = {"Profile": 1, "AccelJerk": 100.0, "DecelJerk": 100.0, "JerkUnits": 2}

#: a script that starts a process of every kind (axes: 1 virtual, 2 servo, 3 rotary
#: servo, 4 feedback only); Step(instance, operands, cycles high, cycles low)
SCENARIO = [
    *POWER_UP[:3],
    Step(
        "MAJ_1",
        {"Axis": 1, "Speed": 100.0, "AccelRate": 2000.0, "DecelRate": 2000.0, **S_CURVE},
        1,
        30,
    ),
    Step(
        "MAG_1",
        {
            "SlaveAxis": 2,
            "MasterAxis": 1,
            "Ratio": 0.5,
            "Clutch": 0,
            "AccelRate": 1000.0,
            "AccelUnits": 0,
        },
        1,
        40,
    ),
    Step(
        "MAM_1",
        {
            "Axis": 3,
            "Position": 90.0,
            "Speed": 360.0,
            "AccelRate": 3600.0,
            "DecelRate": 3600.0,
            **S_CURVE,
        },
        1,
        10,
    ),
    Step(
        "MC_MoveSuperimposed_1",
        {
            "Axis": 3,
            "Distance": 10.0,
            "VelocityDiff": 50.0,
            "Acceleration": 500.0,
            "Deceleration": 500.0,
        },
        1,
        30,
    ),
    Step("MC_HaltSuperimposed_1", {"Axis": 3, "Deceleration": 500.0}, 1, 10),
    Step("MC_GearOut_1", {"Slave": 2}, 1, 20),
    # cams: a position cam on the jogging master with a Pending successor, a time cam
    Step("MCCP_1", {"Cam": 1, "Length": 5, "CamProfile": 1}, 1, 1),
    Step(
        "MAPC_1",
        {
            "SlaveAxis": 3,
            "MasterAxis": 1,
            "CamProfile": 1,
            "ExecutionMode": 1,
            "MasterReference": 1,
            "MasterScaling": 0.1,
        },
        1,
        20,
    ),
    Step(
        "MAPC_1",
        {
            "SlaveAxis": 3,
            "MasterAxis": 1,
            "CamProfile": 1,
            "ExecutionMode": 0,
            "ExecutionSchedule": 1,
            "MasterScaling": 0.1,
        },
        1,
        30,
    ),
    Step("MATC_1", {"Axis": 2, "CamProfile": 1, "TimeScaling": 1000.0}, 1, 20),
    Step("MAS_1", {"Axis": 3, "StopType": 7}, 1, 1),
    Step("MAS_1", {"Axis": 2, "StopType": 8}, 1, 30),
    Step("MDAC_1", {"SlaveAxis": 2, "MasterAxis": 1, "MotionType": 0}, 1, 1),
    Step(
        "MAJ_1",
        {
            "Axis": 2,
            "Speed": 0.2,
            "SpeedUnits": 4,
            "AccelRate": 1.0,
            "AccelUnits": 4,
            "DecelRate": 1.0,
            "DecelUnits": 4,
            "Profile": 0,
        },
        1,
        30,
    ),
    Step("MAS_1", {"Axis": 2, "StopType": 0}, 1, 1),  # a cut while it stops
    Step("MAS_1", {"Axis": 2, "StopType": 0}, 1, 40),
    Step(
        "MC_GearInPos_1",
        {
            "Master": 1,
            "Slave": 2,
            "MasterSyncPosition": 200.0,
            "SlaveSyncPosition": 1000.0,
            "MasterStartDistance": 20.0,
        },
        1,
        60,
    ),
    Step("MAS_1", {"Axis": 3, "StopType": 0}, 1, 30),
    Step("MDAC_1", {"SlaveAxis": 3, "MasterAxis": 1, "MotionType": 2}, 1, 1),
    Step(
        "MAM_1",
        {
            "Axis": 3,
            "Position": 120.0,
            "Speed": 0.5,
            "SpeedUnits": 4,
            "AccelRate": 1.0,
            "AccelUnits": 4,
            "DecelRate": 1.0,
            "DecelUnits": 4,
            "Profile": 0,
        },
        1,
        30,
    ),
    Step("MAS_1", {"Axis": 2, "StopType": 0}, 1, 60),
    Step("MAH_1", {"Axis": 2}, 1, 30),
    # buffered behind the homing: a closure kept for later (kernel Pending)
    Step(
        "MC_MoveRelative_1",
        {
            "Axis": 2,
            "Distance": 5.0,
            "Velocity": 50.0,
            "Acceleration": 500.0,
            "Deceleration": 500.0,
            "BufferMode": 1,
        },
        1,
        30,
    ),
    Step("MAS_1", {"Axis": 1, "StopType": 0}, 1, 40),
]


def build() -> MotionSystem:
    """The demo map's controller with every instruction type (``every_type``): Axis2 homes
    actively (switch, then marker)."""
    return config.load(None).build()


def _kernel_classes() -> set[type]:
    for pkg in (kernel_pkg, instructions_pkg):
        for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            importlib.import_module(m.name)
    found: set[type] = set()
    todo = [Process]
    while todo:
        for sub in todo.pop().__subclasses__():
            if sub not in found:
                found.add(sub)
                todo.append(sub)
    # the server's own classes (other test modules subclass Process for their own tests)
    return {c for c in found if c.__module__.startswith("motion_server.")}


class _Census(statecodec._Pickler):
    """The classes of every object a state holds (what a snapshot captures)."""

    def __init__(self) -> None:
        super().__init__(io.BytesIO(), protocol=statecodec.PROTOCOL)
        self.classes: set[type] = set()

    def reducer_override(self, obj: Any) -> Any:
        self.classes.add(type(obj))
        return super().reducer_override(obj)


def apply(system: MotionSystem, step: Step, trace: list[np.ndarray]) -> None:
    """One step of a script (as ``test_properties.run`` does), every cycle traced."""
    ctl = system.ctl

    def cycle() -> None:
        system.cycle()
        outputs = [
            float(v)
            for inst in system.instances.values()
            for v in inst.outputs.values()
            if isinstance(v, int | float)
        ]
        trace.append(
            np.concatenate(
                [ctl.cmd_pos, ctl.act_pos, ctl.cmd_vel, ctl.act_vel, ctl.arrays.fault, outputs]
            )
        )

    inst = system[step.name]
    for name, value in step.operands.items():
        inst.inputs[name] = value
    if step.name == "MC_Power_1":
        inst.inputs["Enable"] = True
        for _ in range(step.high):
            cycle()
        inst.inputs["Enable"] = step.low % 2 == 0
        for _ in range(step.low):
            cycle()
        return
    inst.inputs[inst.TRIGGER] = True
    for _ in range(step.high):
        cycle()
    inst.inputs[inst.TRIGGER] = False
    for _ in range(step.low):
        cycle()


def check_every_cut(script: list[Step], make: Any = build) -> set[type]:
    """Run ``script``; after every step, a copy through the codec runs the rest beside
    the original: identical traces. The classes the snapshots held."""
    original = make()
    cuts: list[tuple[int, bytes]] = []
    trace: list[np.ndarray] = []
    census = _Census()
    for k, step in enumerate(script):
        census.clear_memo()
        census.dump(original)
        cuts.append((len(trace), statecodec.dumps(original)))
        apply(original, step, trace)
        del k
    for k, (at, data) in enumerate(cuts):
        copy = statecodec.loads(data)
        rest: list[np.ndarray] = []
        for step in script[k:]:
            apply(copy, step, rest)
        assert len(rest) == len(trace) - at
        for n, (a, b) in enumerate(zip(trace[at:], rest, strict=True)):
            assert a.tobytes() == b.tobytes(), f"restored after step {k}: differs at cycle {n}"
    return census.classes


def test_every_process_kind_round_trips_bit_identical() -> None:
    seen = check_every_cut(SCENARIO)
    # every concrete process class of the kernel and the instructions was captured
    abstract = {c for c in _kernel_classes() if any(c in s.__mro__[1:] for s in seen)}
    missing = sorted(
        c.__qualname__ for c in _kernel_classes() if c not in seen and c not in abstract
    )
    assert missing == [], f"process classes no snapshot of the scenario held: {missing}"


def test_a_state_holds_no_class_from_outside() -> None:
    """The restricted unpickler refuses anything not of the kernel by name."""
    evil = pickle.dumps(__import__("os").system)
    with pytest.raises(statecodec.CodecError, match=r"may not hold posix\.system"):
        statecodec.loads(evil)
    with pytest.raises(statecodec.CodecError):
        statecodec.loads(pickle.dumps(io.BytesIO))


@settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(scripts, st.integers(0, 40))
def test_random_scripts_of_every_type_round_trip(script: list[Step], _: int) -> None:
    check_every_cut(script, build_four_axes)
