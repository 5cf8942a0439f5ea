"""Every example against its own fresh server (bench.toml, manual clock, ephemeral port).

Each example must exit 0 (its own checks held) and leave a trace CSV and a valid PNG; the
tests below then check the trace independently, with numbers from the seeds and from
first principles (2 ms cycles, samples every 5 cycles).
"""

from __future__ import annotations

import importlib.util
import itertools
import json
import math
from collections.abc import Callable
from pathlib import Path

import pytest

from motion_clients.plot import is_png
from motion_clients.trace import Trace
from motion_server import config
from motion_server.tagmap import build_tagmap, to_dict
from tests.clients_support import BENCH, ROOT, BenchServer, manual_site

EXAMPLES = sorted((ROOT / "clients" / "examples").glob("[0-9][0-9]_*.py"))
DT = 0.002


def load_main(path: Path) -> Callable[[list[str]], int]:
    spec = importlib.util.spec_from_file_location(f"example_{path.stem}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    main: Callable[[list[str]], int] = module.main
    return main


def run(name: str, tmp_path: Path, opcua: bool = False) -> Trace:
    """Run example ``name`` against a fresh bench server; its trace."""
    path = next(p for p in EXAMPLES if p.stem == name)
    ua = {"data_dir": str(tmp_path / "opcua-data")} if opcua else None
    site = manual_site(config.load(BENCH), opcua=ua)
    map_file = tmp_path / "bench-map.json"
    map_file.write_text(json.dumps(to_dict(build_tagmap(site))), "utf-8")
    with BenchServer(site) as srv:
        argv = ["--port", str(srv.port), "--map", str(map_file), str(tmp_path)]
        if opcua:
            assert srv.runtime is not None and srv.runtime.opcua is not None
            argv[1] = str(srv.runtime.opcua.port)
            argv += ["--cert-dir", str(tmp_path / "client")]
        rc = load_main(path)(argv)
    assert rc == 0, f"{name}: its own checks failed (see its output)"
    png = tmp_path / f"{name}.png"
    assert is_png(png) and png.stat().st_size > 5000
    return Trace.read_csv(tmp_path / f"{name}.csv")


def test_examples_01_to_17_are_all_here() -> None:
    assert [p.stem[:2] for p in EXAMPLES] == [f"{i:02d}" for i in range(1, 18)]


def test_01_power_and_jog(tmp_path: Path) -> None:
    t = run("01_power_and_jog", tmp_path)
    ip = t.column("MAJ_1.IP")
    cycles = t.column("cycle")
    pos = t.column("Slave.CommandPosition")
    first = ip.index(1.0)  # sampled right after the jog's first cycle
    c0 = cycles[first] - 1
    # trapezoidal jog, v = 100 mm/s, a = 1000 mm/s²: x(t) = 500 t² up to 0.1 s, then
    # 5 + 100 (t - 0.1); the first sample is one cycle in: x = 500 · 0.002² = 0.002 mm
    p0 = pos[first] - 500.0 * DT**2
    for k in range(first, len(t)):
        if not ip[k]:
            break
        tt = (cycles[k] - c0) * DT
        expect = 500.0 * tt * tt if tt <= 0.1 else 5.0 + 100.0 * (tt - 0.1)
        assert pos[k] - p0 == pytest.approx(expect, abs=1e-9)
    # at the end: at rest, the stop covered v²/2d = 5 mm after 25 mm of jog
    assert pos[-1] - p0 == pytest.approx(30.0, abs=1e-9)
    assert t.column("Slave.ActualPosition")[-1] == pytest.approx(pos[-1], abs=1e-3)
    # the actual trails the command while moving (a real drive lag)
    lag = [c - a for c, a in zip(pos, t.column("Slave.ActualPosition"), strict=True)]
    assert max(lag) > 0.1


def test_02_mag_fraction_ratio_is_exact_in_counts(tmp_path: Path) -> None:
    t = run("02_mag_fraction_ratio", tmp_path)
    master = [round(p * 1000) for p in t.column("Master.CommandPosition")]
    slave = [round(p * 1000) for p in t.column("Slave.CommandPosition")]
    moving = [k for k in range(len(t)) if master[k] != master[0]]
    k0 = moving[0] - 1
    for k in moving:
        assert slave[k] - slave[k0] == (master[k] - master[k0]) // 3
    assert master[-1] - master[k0] > 90_000  # about a second at 100 mm/s
    assert t.column("Slave.CommandVelocity")[-1] == pytest.approx(100.0 / 3.0, abs=1e-6)


def test_03_mag_clutch_ramps_at_accel_rate_and_reverses(tmp_path: Path) -> None:
    t = run("03_mag_clutch_and_reverse", tmp_path)
    v = t.column("Slave.CommandVelocity")
    dv = [b - a for a, b in itertools.pairwise(v)]
    # 5 cycles between samples: at most 500 mm/s² · 0.01 s = 5 mm/s per sample
    assert max(abs(d) for d in dv) <= 5.0 + 1e-9
    assert 50.0 in [round(x, 9) for x in v] and v[-1] == pytest.approx(-50.0, abs=1e-9)
    # the reversal from +50 to -50 takes 100 / 500 = 0.2 s: 20 samples of 5 cycles
    last_plus = max(k for k, x in enumerate(v) if x == pytest.approx(50.0, abs=1e-9))
    first_minus = min(k for k, x in enumerate(v) if x == pytest.approx(-50.0, abs=1e-9))
    span = t.column("cycle")[first_minus] - t.column("cycle")[last_plus]
    assert 100 <= span <= 105  # 100 cycles of ramp, plus the sample spacing


def test_04_gear_in_follows_the_hand_wheel_one_to_one(tmp_path: Path) -> None:
    t = run("04_mc_gearin_handwheel", tmp_path)
    wheel = t.column("HandWheel.ActualPosition")
    slave = t.column("PSlave.CommandPosition")
    start = t.column("GearIn_1.InGear").index(1.0)
    for k in range(start, len(t)):
        assert slave[k] - slave[start] == pytest.approx(wheel[k] - wheel[start], abs=1e-9)
    assert max(wheel) - wheel[start] == pytest.approx(20.0, abs=1e-9)
    assert wheel[-1] - wheel[start] == pytest.approx(5.0, abs=1e-9)


def test_05_gear_out_keeps_the_velocity_until_mc_stop(tmp_path: Path) -> None:
    t = run("05_mc_gearout_keeps_velocity", tmp_path)
    state = t.column("PSlave.PLCopenState")
    v = t.column("PSlave.CommandVelocity")
    master = t.column("PMaster.CommandVelocity")
    free = [k for k, s in enumerate(state) if s == 7]  # ContinuousMotion after GearOut
    assert free and all(v[k] == pytest.approx(200.0, abs=1e-9) for k in free)
    assert min(master[k] for k in free) == pytest.approx(20.0, abs=1e-9)  # master slowed
    assert 8.0 in state[: free[0]]  # SynchronizedMotion before
    assert state[-1] == 2.0 and v[-1] == 0.0


def test_06_gear_in_pos_rotary_seed_example(tmp_path: Path) -> None:
    t = run("06_mc_gearinpos_rotary", tmp_path)
    m = t.column("RotMaster.CommandPosition")
    s = t.column("RotSlave.CommandPosition")
    start = t.column("GearInPos_1.StartSync").index(1.0)
    sync = t.column("GearInPos_1.InSync").index(1.0)
    # the slave waits at 45° until the master passes 270° (360° - 90° start distance);
    # the block sees the master's actual position at the cycle start, 0.36° behind
    assert all(x == pytest.approx(45.0, abs=1e-9) for x in s[start - 5 : start])
    assert m[start - 1] - 0.36 < 270.0 <= m[start] - 0.36 + 1e-9
    # locked on once the master wrapped past 360°: 90° ahead of the master's actual
    # position sampled at the cycle start (one cycle, 0.36°, behind its command)
    assert m[sync] < 90.0
    for k in range(sync, len(t)):
        assert s[k] == pytest.approx((m[k] - 0.36 + 90.0) % 360.0, abs=1e-6)


def test_07_combine_axes_adds_then_subtracts(tmp_path: Path) -> None:
    t = run("07_mc_combineaxes_add_sub", tmp_path)
    v1, v2 = t.column("PMaster.CommandVelocity"), t.column("PMaster2.CommandVelocity")
    vs = t.column("PSlave.CommandVelocity")
    added = [k for k in range(len(t)) if vs[k] == pytest.approx(130.0, abs=1e-9)]
    subtracted = [k for k in range(len(t)) if vs[k] == pytest.approx(70.0, abs=1e-9)]
    assert added and subtracted and added[-1] < subtracted[0]
    for k in added:
        assert vs[k] == pytest.approx(v1[k] + v2[k], abs=1e-9)
    for k in subtracted:
        assert vs[k] == pytest.approx(v1[k] - v2[k], abs=1e-9)
    # in sync, each slave increment is the masters' increments combined
    p1, p2 = t.column("PMaster.CommandPosition"), t.column("PMaster2.CommandPosition")
    ps = t.column("PSlave.CommandPosition")
    for k in subtracted[1:]:
        d = (p1[k] - p1[k - 1]) - (p2[k] - p2[k - 1])
        assert ps[k] - ps[k - 1] == pytest.approx(d, abs=1e-9)


def test_08_mgs_programmed_stop_modes(tmp_path: Path) -> None:
    t = run("08_mgs_programmed_modes", tmp_path)
    ip = t.column("MGS_1.IP")
    pc = t.column("MGS_1.PC")
    k0 = ip.index(1.0)  # the sample right after the MGS scan
    final = {"FastStop": 2, "FastDisable": 0, "HardDisable": 0, "FastShutdown": 4}
    final["HardShutdown"] = 4
    for name, state in final.items():
        assert t.column(f"{name}.AxisState")[-1] == state
        assert t.column(f"{name}.ActualVelocity")[-1] == pytest.approx(0.0, abs=1e-9)
    # hard modes: the drive is off at the first scan (Axis Ready / Shutdown at once)
    assert t.column("HardDisable.AxisState")[k0] == 0
    assert t.column("HardShutdown.AxisState")[k0] == 4
    # fast stop: at rest after V/D = 25 cycles, 2.5 mm on (sampled 1 cycle after the scan)
    pos = t.column("FastStop.CommandPosition")
    cycles = t.column("cycle")
    rest = next(k for k in range(k0, len(t)) if pos[k] == pos[-1])
    assert cycles[rest] - cycles[k0] + 1 <= 25 + 4
    assert cycles[rest - 1] - cycles[k0] + 1 < 25
    # coasting at C = 500 mm/s² from 100 mm/s takes up to 0.2 s: PC within 100 cycles + 5
    done = pc.index(1.0)
    assert 25 < cycles[done] - cycles[k0] + 1 <= 105
    assert not any(ip[done:])


def test_09_mdac_changes_the_master_at_the_next_motion_instruction(tmp_path: Path) -> None:
    t = run("09_mdac_change_master", tmp_path)
    v = t.column("Slave.CommandVelocity")
    ac1, ac2 = t.column("MDAC_1.AC"), t.column("MDAC_2.AC")
    switch = ac2.index(1.0)
    assert all(a == 0.0 for a in ac1[switch:])
    # before the switch the slave tracks A at 0.5 · 100, after it B at 1.0 · 80
    assert v[switch - 1] == pytest.approx(50.0, abs=1e-9)
    assert v[-1] == pytest.approx(80.0, abs=1e-9)
    assert t.column("MAJ_2.TrackingMaster")[-1] == 1.0
    # no jump at the switch: at most 0.05 mm/mm per master mm (80 mm/s · 0.01 s) per sample
    dv = [abs(b - a) for a, b in itertools.pairwise(v[switch - 1 :])]
    assert max(dv) <= 0.05 * 80.0 * 0.01 * 80.0 + 1e-6
    assert math.isfinite(sum(v))


def test_10_opcua_scada_subscription(tmp_path: Path) -> None:
    """Over OPC UA (Basic256Sha256, the bench user); the example itself checks what the
    subscription delivered. The trace: the slave geared at 0.5 · 100 = 50 mm/s."""
    t = run("10_opcua_scada_subscription", tmp_path, opcua=True)
    ip = t.column("MAG_1.IP")
    vm, v = t.column("Master.CommandVelocity"), t.column("Slave.CommandVelocity")
    geared = ip.index(1.0)
    for a, b in zip(vm[geared:], v[geared:], strict=True):
        assert b == pytest.approx(0.5 * a, abs=1e-9)  # no clutch: locked at once
    k = next(i for i in range(geared, len(t)) if vm[i] == pytest.approx(100.0, abs=1e-9))
    assert v[-1] == pytest.approx(50.0, abs=1e-9)
    p = t.column("Slave.CommandPosition")
    # 5 cycles of 2 ms at 50 mm/s between samples: 0.5 mm
    for a, b in itertools.pairwise(p[k:]):
        assert b - a == pytest.approx(0.5, abs=1e-9)


def test_11_mc_home_rotary_switch_then_marker(tmp_path: Path) -> None:
    t = run("11_mc_home_rotary_switch_marker", tmp_path)
    v = t.column("RotSlave.CommandVelocity")
    x = t.column("RotSlave.CommandPosition")
    done = t.column("Home_RotSlave.Done").index(1.0)
    # the search at the home speed forward, the back-off at the return speed reverse
    assert max(v[:done]) == pytest.approx(90.0, abs=1e-9)
    assert min(v[:done]) == pytest.approx(-10.0, abs=1e-9)
    assert 5 in t.column("RotSlave.PLCopenState")[:done]  # Homing
    # done at the home position, 45° (MC_Home's Position, home_offset 0)
    assert x[done] == pytest.approx(45.0, abs=1e-9)
    # after MC_SetPosition -15° the cam reads [35°, 55°]: on at 40°, off at 20°
    switch = t.column("RotSlave.HomeSwitch")
    on = [k for k in range(done, len(t)) if switch[k]]
    assert on and all(35.0 <= x[k] <= 55.0 for k in on)
    assert x[-1] == pytest.approx(20.0, abs=1e-9) and not switch[-1]


def test_12_mah_to_a_marker_then_mrp(tmp_path: Path) -> None:
    t = run("12_mah_marker_and_mrp", tmp_path)
    ip, pc = t.column("MAH_1.IP"), t.column("MAH_1.PC")
    x, v = t.column("Slave.CommandPosition"), t.column("Slave.CommandVelocity")
    first, done = ip.index(1.0), pc.index(1.0)
    # unidirectional: forward only, at most the home speed, 20 mm/s
    assert all(0.0 <= v[k] <= 20.0 + 1e-9 for k in range(first, done))
    assert max(v[first:done]) == pytest.approx(20.0, abs=1e-9)
    # the sequence ends at the home position 0 mm, then MRP shifts it to 102.5 mm
    assert x[done] == pytest.approx(0.0, abs=1e-9)
    assert x[-1] == pytest.approx(102.5, abs=1e-6) and v[-1] == 0.0
    # on a fresh server the load starts at raw 0: the first marker is at 2.5 mm, where
    # the coordinates shift so that it reads -5 mm: one drop of 7.5 mm less the travel
    # between two samples (5 cycles at 20 mm/s: 0.2 mm). The marker sees the load, which
    # trails the command by 2v/ω = 40/(2π·40) mm; the shift comes one cycle (0.04 mm)
    # after the crossing at the latest
    lag = 2.0 * 20.0 / (2.0 * math.pi * 40.0)
    assert x[first - 1] == 0.0
    drops = [k for k in range(first, done) if x[k + 1] - x[k] < -1.0]
    assert len(drops) == 1
    k = drops[0]
    assert 2.5 + lag - 0.2 < x[k] <= 2.5 + lag + 0.04 + 1e-9
    assert -7.5 < x[k + 1] - x[k] <= -7.5 + 0.2 + 1e-9


def test_13_read_blocks_and_the_lag_limit(tmp_path: Path) -> None:
    t = run("13_mc_read_blocks_lag_limit", tmp_path)
    limit = t.column("LagLimit_PSlave.Value")
    stop = t.column("Status_PSlave.ErrorStop")
    moving = t.column("Status_PSlave.ContinuousMotion")
    err = t.column("AxisError_PSlave.AxisErrorID")
    va = t.column("PSlave.ActualVelocity")
    # the limit as MC_ReadParameter saw it: 0 (off), 1.2, 0.5, 0 again
    steps = [limit[0]] + [limit[k] for k in range(1, len(t)) if limit[k] != limit[k - 1]]
    assert steps == [0.0, 1.2, 0.5, 0.0]
    # at 1.2 mm the move runs (steady error 2v/ω = 0.796 mm): no fault
    under = [k for k in range(len(t)) if limit[k] == 1.2]
    assert any(moving[k] for k in under) and not any(stop[k] for k in under)
    assert max(va[k] for k in under) == pytest.approx(100.0, abs=1e-6)
    # the fault comes with the 0.5 mm limit once the monitoring is on again (it runs
    # on at 0.5 mm while it is off), the position error bit with it
    first = stop.index(1.0)
    assert limit[first] == 0.5 and err[first] == 1.0
    unwatched = [k for k in range(first) if limit[k] == 0.5]
    assert len(unwatched) >= 2 and all(moving[k] for k in unwatched)
    assert err[-1] == 0.0 and not stop[-1]


def test_14_superimposed_on_a_gear_halt_then_additive(tmp_path: Path) -> None:
    t = run("14_mc_movesuperimposed_and_additive", tmp_path)
    state = t.column("PSlave.PLCopenState")
    v = t.column("PSlave.CommandVelocity")
    master = t.column("PMaster.CommandVelocity")
    covered = t.column("Super_PSlave.CoveredDistance")
    geared = [k for k, s in enumerate(state) if s == 8]  # SynchronizedMotion
    # the superimposed move adds at most its VelocityDiff (50 mm/s) to the gear, both ways
    extra = [v[k] - master[k] for k in geared]
    assert max(extra) == pytest.approx(50.0, abs=1e-9)
    assert min(extra) == pytest.approx(-50.0, abs=1e-9)
    assert max(covered) == pytest.approx(10.0, abs=1e-9)
    # MC_Halt brought the slave to rest while the master ran on
    rest = state.index(2.0, geared[-1])
    assert v[rest] == 0.0 and master[rest] == pytest.approx(100.0, abs=1e-9)
    # MC_MoveAdditive: the MC_MoveAbsolute target (100 mm) + 25 mm, exactly
    assert t.column("PSlave.CommandPosition")[-1] == 125.0
    assert state[-1] == 2.0 and v[-1] == 0.0


def test_15_override_scales_the_running_jog(tmp_path: Path) -> None:
    t = run("15_mc_setoverride_jog", tmp_path)
    v = t.column("PSlave.CommandVelocity")
    state = t.column("PSlave.PLCopenState")
    vel_f = t.column("Override_PSlave.VelFactor")
    acc_f = t.column("Override_PSlave.AccFactor")
    on = t.column("Override_PSlave.Enabled")
    enabled = [k for k in range(len(t)) if on[k]]
    # the override never changes the state: ContinuousMotion throughout
    assert enabled and all(state[k] == 7.0 for k in enabled)
    # VelFactor 0.5 of 100 mm/s: a plateau at 50; VelFactor 0: at rest, still in motion
    half = [v[k] for k in enabled if vel_f[k] == 0.5]
    assert half[-1] == pytest.approx(50.0, abs=1e-9) and min(half) >= 50.0 - 1e-9
    assert any(v[k] == 0.0 for k in enabled if vel_f[k] == 0.0)
    # back up with AccFactor 0.5: 500 mm/s^2, at most 5 mm/s per 10 ms sample
    up = [k for k in enabled if vel_f[k] == 1.0 and acc_f[k] == 0.5]
    steps = [v[k] - v[k - 1] for k in up if k > 0]
    assert max(steps) <= 500.0 * 5 * DT + 1e-9
    assert v[up[-1]] == pytest.approx(100.0, abs=1e-9)
    assert v[-1] == 0.0


def hermite(p0: float, p1: float, m0: float, m1: float, h: float, u: float) -> tuple[float, float]:
    """The cubic from (0, p0) with slope m0 to (h, p1) with slope m1 at ``u``: (value,
    slope)."""
    t = u / h
    f = (
        (2 * t**3 - 3 * t**2 + 1) * p0
        + (t**3 - 2 * t**2 + t) * h * m0
        + (-2 * t**3 + 3 * t**2) * p1
        + (t**3 - t**2) * h * m1
    )
    df = (6 * t**2 - 6 * t) * p0 / h + (3 * t**2 - 4 * t + 1) * m0
    df += (-6 * t**2 + 6 * t) * p1 / h + (3 * t**2 - 2 * t) * m1
    return f, df


def knife(c: float) -> tuple[float, float]:
    """Example 16's table (0, 0) (60, 60) (240, 180) (420, 300) (480, 360), linear, cubic,
    cubic, linear; the spline's slopes by hand: 1 at 60 and 420 (the linear neighbours),
    m at 240 from 180·1 + 2·360·m + 180·1 = 3·(180·2/3 + 180·2/3): m = 1/2. (knife °
    after c mm of conveyor, unwound, 360° per 480 mm; its slope °/mm)."""
    k, x = divmod(c, 480.0)
    if x <= 60.0:
        f, df = x, 1.0
    elif x <= 240.0:
        f, df = hermite(60.0, 180.0, 1.0, 0.5, 180.0, x - 60.0)
    elif x <= 420.0:
        f, df = hermite(180.0, 300.0, 0.5, 1.0, 180.0, x - 240.0)
    else:
        f, df = 300.0 + (x - 420.0), 1.0
    return 360.0 * k + f, df


def test_16_rotary_knife_one_turn_per_product_synchronous_in_the_cut(tmp_path: Path) -> None:
    # the closed form at the table's points and at the cubic segments' middles
    # (Hermite basis 1/2, 1/8, 1/2, -1/8): 60 + 22.5 + 90 - 11.25 and 90 + 11.25 + 150 - 22.5
    assert [knife(c)[0] for c in (60.0, 150.0, 240.0, 330.0, 420.0, 480.0)] == [
        60.0,
        131.25,
        180.0,
        228.75,
        300.0,
        360.0,
    ]
    t = run("16_mapc_rotary_knife", tmp_path)
    conv, kn = t.column("Conveyor.CommandPosition"), t.column("Knife.CommandPosition")
    vc, vk = t.column("Conveyor.CommandVelocity"), t.column("Knife.CommandVelocity")
    status = [int(s) for s in t.column("Knife.MotionStatus")]
    lock = next(i for i, s in enumerate(status) if s >> 13 & 1)  # the MAPC sample
    # the conveyor rests at the lock, so the lock is at conveyor conv[lock]; the next
    # sample is the jog's first cycle: 4000 mm/s² · dt² / 2 = 0.008 mm on
    assert vc[lock] == 0.0
    assert conv[lock + 1] - conv[lock] == pytest.approx(4000.0 * DT**2 / 2.0, abs=1e-12)
    c0, k0 = conv[lock], kn[lock]
    moving = [i for i in range(lock, len(t)) if vc[i] > 0.0]
    # PositionCam (8) and PositionCamLock (13) set from the lock until MAS Position Cam
    locked = [i for i in range(lock, len(t)) if status[i] >> 13 & 1]
    assert locked == list(range(lock, locked[-1] + 1)) and locked[-1] > moving[-1]
    assert all(status[i] >> 8 & 1 for i in locked)
    assert status[-1] >> 8 & 1 == 0 and status[-1] >> 13 & 1 == 0
    travel = 0.0
    for i in locked:
        expected, slope = knife(conv[i] - c0)
        # the rotary knife reads modulo 360; its unwound travel follows the cam exactly
        if i > lock:
            d = kn[i] - kn[i - 1]
            travel += d - 360.0 * round(d / 360.0)
        assert travel == pytest.approx(expected, abs=1e-6)
        assert kn[i] == pytest.approx((k0 + expected) % 360.0, abs=1e-6)
        assert vk[i] == pytest.approx(slope * vc[i], abs=1e-6)
        x = (conv[i] - c0) % 480.0
        if x <= 60.0 or x >= 420.0:  # the cut: the blade at the conveyor's speed
            assert vk[i] == pytest.approx(vc[i], abs=1e-9)
    # one 360° turn per 480 mm product: at least two whole products ran
    assert conv[moving[-1]] - c0 > 960.0
    assert travel == pytest.approx(720.0 + knife(conv[locked[-1]] - c0 - 960.0)[0], abs=1e-6)
    # at speed (400 mm/s) the knife slows to half of it at 240 mm: 200 °/s at the least
    assert min(vk[i] for i in moving if vc[i] == pytest.approx(400.0)) == pytest.approx(
        200.0, abs=1.0
    )


def shear(x: float) -> tuple[float, float]:
    """Example 17's table over one 500 mm period: (0, 0) cubic, (100, 50) linear, (250,
    200) cubic, (500, 0), the selection's end slopes 0. The first segment runs from slope 0
    to its linear neighbour's 1: c = (3·50/100 - 0 - 1)/100 = 0.005, d = (0 + 1 -
    2·50/100)/100² = 0, the parabola 0.005·x²; the return from slope 1 at 250 to 0 at 500.
    (shear mm at x mm of line into a period; its slope)."""
    x %= 500.0
    if x <= 100.0:
        return 0.005 * x * x, 0.01 * x
    if x <= 250.0:
        return 50.0 + (x - 100.0), 1.0
    return hermite(200.0, 0.0, 1.0, 0.0, 250.0, x - 250.0)


def test_17_flying_shear_in_sync_one_pulse_per_cut_then_cam_out(tmp_path: Path) -> None:
    # the closed form at the points and the middles (the return: 100 + 250·1/8 = 131.25)
    assert [shear(x)[0] for x in (0.0, 50.0, 100.0, 250.0, 375.0, 500.0)] == [
        0.0,
        12.5,
        50.0,
        200.0,
        131.25,
        0.0,
    ]
    t = run("17_mc_camin_flying_shear", tmp_path)
    cycle = t.column("cycle")
    m, s = t.column("Line.CommandPosition"), t.column("Shear.CommandPosition")
    vm, vs = t.column("Line.CommandVelocity"), t.column("Shear.CommandVelocity")
    state = t.column("Shear.PLCopenState")
    in_sync, eop = t.column("CamIn_Shear.InSync"), t.column("CamIn_Shear.EndOfProfile")
    synced = [i for i, v in enumerate(in_sync) if v]
    c = synced[0]
    assert synced == list(range(c, synced[-1] + 1))
    # every cycle sampled from the cycle before the coupling to the end of the cam
    assert all(cycle[i] - cycle[i - 1] == 1 for i in range(c, synced[-1] + 1))
    # relative slave: shear = shear at coupling + F(line) - F(line at coupling); the
    # coupling sees the line where the previous cycle left it, sample c - 1
    offset = s[c - 1] - shear(m[c - 1])[0]
    assert state[c - 1] == 2.0 and vs[c - 1] == 0.0
    cut = 0
    for i in synced:
        f, slope = shear(m[i])
        assert s[i] - f == pytest.approx(offset, abs=1e-6)
        assert vs[i] == pytest.approx(slope * vm[i], abs=1e-6)
        assert state[i] == 8.0  # SynchronizedMotion
        if 100.0 <= m[i] % 500.0 <= 250.0:  # the cut: the shear at the line's speed
            assert vs[i] == pytest.approx(vm[i], abs=1e-9)
            cut += 1
        # one EndOfProfile pulse in the cycle the line completes a period
        assert bool(eop[i]) == (m[i] // 500.0 > m[i - 1] // 500.0), (m[i - 1], m[i])
    assert sum(eop[i] for i in synced) >= 2 and cut > 0
    # MC_CamOut in the cut: ContinuousMotion at the line's speed, kept until MC_Stop
    free = [i for i in range(synced[-1], len(t)) if state[i] == 7.0]
    assert free and free[0] == synced[-1] + 1
    assert all(vs[i] == pytest.approx(1000.0, abs=1e-9) for i in free)
    assert vs[-1] == 0.0 and state[-1] == 2.0
