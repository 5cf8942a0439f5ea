"""Injected faults over the network, as an HMI sees them: the status words, the stop, the
reset (``kernel/faults.py``; tags ``<Axis>.Inject...``, ``ServoFault``, ``AxisErrorID``).

The demo map's Axis2 is a servo axis with a maximum deceleration of 20,000 mm/s² and a
coast deceleration of 500 mm/s², at a 2 ms period: a planner stop takes 40 mm/s off the
command per cycle (100 -> 60 -> 20 -> 0), a coasting axis 1 mm/s off its actual velocity.
ServoFault bits and AxisErrorID (= 1 + the bit) are the Logix ServoFaultBits of Rockwell
MOTION-RM002.
"""

from __future__ import annotations

from typing import Any

import pytest
from asyncua import Client

from motion_clients import MotionClient
from motion_server import config
from motion_server.kernel import AxisFault, AxisState, ErrorCode, PLCopenState
from tests.clients_support import serving
from tests.integration.test_opcua_roles import roles_site, write
from tests.opcua_support import running, secure_client

SPEED = 100.0
DECEL_STEP = 40.0  # 20,000 mm/s² x 2 ms
COAST_STEP = 1.0  # 500 mm/s² x 2 ms

#: tag -> (AxisFault bit, ServoFault bit, direction of the jog, keeps the drive on)
CASES: dict[str, tuple[AxisFault, int, int, bool]] = {
    "InjectDriveFault": (AxisFault.DRIVE, 9, 1, False),
    "InjectFeedbackLoss": (AxisFault.FEEDBACK, 4, 1, False),
    "InjectFollowingError": (AxisFault.POSITION_ERROR, 8, -1, False),
    "InjectPosHardOvertravel": (AxisFault.POS_HARD_OVERTRAVEL, 2, 1, True),
    "InjectNegHardOvertravel": (AxisFault.NEG_HARD_OVERTRAVEL, 3, -1, True),
    "InjectPosSoftOvertravel": (AxisFault.POS_SOFT_OVERTRAVEL, 0, 1, True),
    "InjectNegSoftOvertravel": (AxisFault.NEG_SOFT_OVERTRAVEL, 1, -1, True),
}
STATUS = ["AxisFault", "ServoFault", "AxisErrorID", "AxisState", "PLCopenState"]


async def status(mc: MotionClient, axis: str = "Axis2") -> dict[str, Any]:
    values = await mc.read_many([f"{axis}.{f}" for f in STATUS])
    return {k.split(".")[1]: v for k, v in values.items()}


async def jog(mc: MotionClient, sign: int, axis: int = 2) -> Any:
    return await mc.trigger(
        "MAJ_1",
        Axis=axis,
        Direction=0 if sign > 0 else 1,
        Speed=SPEED,
        AccelRate=20000.0,
        DecelRate=20000.0,
    )


@pytest.mark.parametrize("tag", list(CASES))
async def test_each_fault_kind_status_stop_and_reset(tag: str) -> None:
    bit, servo_bit, sign, drive_on = CASES[tag]
    with serving(config.load(None)) as (srv, tagmap):
        async with MotionClient.connect(tagmap, "modbus", "127.0.0.1", srv.port) as mc:
            assert (await mc.trigger("MSO_1", Axis=2)).ok
            assert (await jog(mc, sign)).ok
            await mc.step(20)
            assert await mc.read("Axis2.CommandVelocity") == sign * SPEED
            v0 = await mc.read("Axis2.ActualVelocity")
            assert await status(mc) == {
                "AxisFault": 0,
                "ServoFault": 0,
                "AxisErrorID": 0,
                "AxisState": AxisState.SERVO_CONTROL,
                "PLCopenState": PLCopenState.CONTINUOUS_MOTION,
            }

            # -- the status a client sees
            await mc.write(f"Axis2.{tag}", True)
            assert await status(mc) == {
                "AxisFault": bit,
                "ServoFault": 1 << servo_bit,
                "AxisErrorID": 1 + servo_bit,
                "AxisState": AxisState.SERVO_CONTROL if drive_on else AxisState.AXIS_FAULTED,
                "PLCopenState": PLCopenState.ERRORSTOP,
            }
            assert await mc.read(f"Axis2.{tag}") is True

            # -- the stop
            if drive_on:  # Stop Planner: the command ramps to rest at the maximum deceleration
                for expected in (60.0, 20.0, 0.0):
                    await mc.step(1)
                    assert await mc.read("Axis2.CommandVelocity") == sign * expected
            else:  # Disable Drive: the axis coasts
                await mc.step(5)
                coasting = await mc.read("Axis2.ActualVelocity")
                assert coasting == pytest.approx(v0 - sign * 5 * COAST_STEP, abs=1e-9)
            assert await mc.read("MAJ_1.IP") is False

            # -- the reset
            if drive_on:
                # reset while beyond the limit: allowed, so that the axis can come back
                assert (await mc.trigger("MAFR_1", Axis=2)).ok
                seen = await status(mc)
                assert (seen["AxisFault"], seen["PLCopenState"]) == (0, PLCopenState.STANDSTILL)
                # further beyond: refused by the axis (ER, ERR 1010), the fault again
                assert (await jog(mc, sign)).ok  # DN at initiation
                await mc.step(2)
                assert await mc.read("MAJ_1.ER") is True
                assert await mc.read("MAJ_1.ERR") == ErrorCode.OVERTRAVEL
                assert await mc.read("Axis2.AxisFault") == bit
                await mc.step(5)
                # back: reset, jog the other way; the cause ends once back inside
                assert (await mc.trigger("MAFR_1", Axis=2)).ok
                assert (await jog(mc, -sign)).ok
                for _ in range(50):
                    await mc.step(1)
                    if await mc.read(f"Axis2.{tag}") is False:
                        break
                assert await mc.read(f"Axis2.{tag}") is False
                assert await mc.read("MAJ_1.IP") is True
                assert (await status(mc))["AxisFault"] == 0
            else:
                # held: MAFR is done and the fault comes back at once; MC_Reset says so
                assert (await mc.trigger("MAFR_1", Axis=2)).ok
                assert (await status(mc))["AxisState"] == AxisState.AXIS_FAULTED
                out = await mc.trigger("MC_Reset_1", Axis=2)
                assert not out.ok and await mc.read("MC_Reset_1.ErrorID") == 20
                # removed: the reset clears it
                await mc.write(f"Axis2.{tag}", False)
                assert (await status(mc))["AxisFault"] == bit  # latched until the reset
                assert (await mc.trigger("MAFR_1", Axis=2)).ok
                assert await status(mc) == {
                    "AxisFault": 0,
                    "ServoFault": 0,
                    "AxisErrorID": 0,
                    "AxisState": AxisState.AXIS_READY,
                    "PLCopenState": PLCopenState.DISABLED,
                }
                assert (await mc.trigger("MSO_1", Axis=2)).ok
                assert await mc.read("Axis2.AxisState") == AxisState.SERVO_CONTROL


async def test_feedback_loss_on_the_hand_wheel() -> None:
    with serving(config.load(None)) as (srv, tagmap):
        assert "Axis4.InjectDriveFault" not in tagmap and "Axis4.InjectFeedbackLoss" in tagmap
        async with MotionClient.connect(tagmap, "modbus", "127.0.0.1", srv.port) as mc:
            await mc.write("Axis4.InjectFeedbackLoss", True)
            seen = await status(mc, "Axis4")
            assert (seen["AxisState"], seen["ServoFault"], seen["AxisErrorID"]) == (3, 16, 5)
            await mc.write("Axis4.InjectFeedbackLoss", False)
            assert (await mc.trigger("MAFR_1", Axis=4)).ok
            assert (await status(mc, "Axis4"))["AxisState"] == AxisState.AXIS_READY


async def test_an_operator_injects_and_resets_over_opcua(tmp_path: Any) -> None:
    """Axis1 of the OPC UA test site is virtual: its planner's soft travel limits."""
    async with running(roles_site(tmp_path)) as rt:
        client: Client = await secure_client(rt, tmp_path, "operator")
        await client.connect()
        try:
            assert await write(rt, client, "MSO_1.Axis", 1) == 0
            assert await write(rt, client, "MSO_1.Execute", True) == 0
            rt.cycle(1)
            assert await write(rt, client, "Axis1.InjectNegSoftOvertravel", True) == 0
            rt.cycle(1)
            assert rt.image.read("Axis1.AxisFault") == AxisFault.NEG_SOFT_OVERTRAVEL
            assert rt.image.read("Axis1.ServoFault") == 1 << 1
            assert rt.image.read("Axis1.PLCopenState") == PLCopenState.ERRORSTOP
            assert await write(rt, client, "MAFR_1.Axis", 1) == 0
            assert await write(rt, client, "MAFR_1.Execute", True) == 0
            rt.cycle(1)
            assert rt.image.read("MAFR_1.DN") is True
            assert rt.image.read("Axis1.AxisFault") == 0
            assert rt.image.read("Axis1.PLCopenState") == PLCopenState.STANDSTILL
        finally:
            await client.disconnect()
