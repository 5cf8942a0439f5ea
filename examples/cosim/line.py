"""The line example: two controller FMUs and a plant FMU in lockstep under libcosim.

- ``infeed`` (``infeed.toml``) drives the conveyor belt: MSO, then a jog at 250 mm/s;
- ``conveyor`` (``conveyor.py``, the plant) carries products every 100 mm, each a few mm
  off its nominal place, past a registration sensor;
- ``cutter`` (``cutter.toml``) gears a knife 1:1 to the belt's actual position (a
  feedback-only axis fed from the infeed's encoder) and, at every rising edge of the
  sensor, runs an incremental MAM of the product's measured offset change: the knife's
  phase follows the products. That closes the loop: plant sensor -> controller.

Two existing masters run it, each stepping the three FMUs in lockstep every 2 ms and
moving the connected values between steps: Open Simulation Platform's libcosim
(``libcosimpy``, :func:`run`) and fmpy's SSP master (``fmpy.ssp.simulation.simulate_ssp``,
:func:`run_fmpy`), which takes the line as an SSP archive (:func:`ssp`: the three FMUs
and a ``SystemStructure.ssd`` wiring them). libcosim takes FMI 2.0 only, so the FMUs are
FMI 2.0.

    python examples/cosim/line.py [--master libcosim|fmpy] [--seconds 3] [--plot line.png]
                                  [--dir build/]
"""

from __future__ import annotations

import argparse
import tempfile
import zipfile
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

HERE = Path(__file__).resolve().parent
PERIOD = 0.002
#: when the operator's triggers rise (steps of 2 ms): servos on, knife geared, belt jogs
TRIGGERS = [
    (1, "infeed", "BeltOn.Execute"),
    (1, "cutter", "KnifeOn.Execute"),
    (5, "cutter", "KnifeGear.Execute"),
    (10, "infeed", "BeltJog.Execute"),
]
#: (from instance, output) -> (to instance, input)
CONNECTIONS = [
    (("infeed", "Belt.ActualPosition"), ("conveyor", "belt_position")),
    (("infeed", "Belt.ActualPosition"), ("cutter", "Belt.FeedbackInput")),
    (("conveyor", "sensor"), ("cutter", "Phase.Execute")),
    (("conveyor", "correction"), ("cutter", "Phase.Position")),
]
#: what the run records every step
TRACE = [
    ("infeed", "Belt.ActualPosition"),
    ("conveyor", "sensor"),
    ("conveyor", "correction"),
    ("conveyor", "products"),
    ("cutter", "Belt.ActualPosition"),
    ("cutter", "Knife.CommandPosition"),
    ("cutter", "Knife.ActualPosition"),
    ("cutter", "Phase.IP"),
    ("cutter", "KnifeGear.IP"),
]


def build(dest: Path) -> dict[str, Path]:
    """The three FMUs (FMI 2.0), built with pythonfmu: the controllers by
    ``motion-server fmu``, the plant by pythonfmu's own builder."""
    from pythonfmu import FmuBuilder

    from motion_server.fmi.build import build_fmu

    dest.mkdir(parents=True, exist_ok=True)
    fmus = {
        "infeed": build_fmu(HERE / "infeed.toml", dest / "infeed.fmu", 2),
        "cutter": build_fmu(HERE / "cutter.toml", dest / "cutter.fmu", 2),
    }
    fmus["conveyor"] = Path(FmuBuilder.build_FMU(HERE / "conveyor.py", dest=dest))
    return fmus


def run(fmus: dict[str, Path], seconds: float = 3.0, connect: bool = True) -> dict[str, Any]:
    """Run the line for ``seconds`` under libcosim; the trace, one list per
    ``instance.variable`` (``connect`` False: the plant's sensor is not wired to the
    cutter, the loop open)."""
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    execution = CosimExecution.from_step_size(step_size=round(PERIOD * 1e9))
    index: dict[str, int] = {}
    refs: dict[tuple[str, str], tuple[int, int]] = {}
    for name in ("infeed", "conveyor", "cutter"):
        slave = execution.add_local_slave(CosimLocalSlave(str(fmus[name]), name))
        index[name] = slave
        for v in execution.slave_variables(slave):
            refs[(name, v.name.decode())] = (v.reference, int(v.type))
    connect_by_type = {
        int(CosimVariableType.REAL.value): execution.connect_real_variables,
        int(CosimVariableType.BOOLEAN.value): execution.connect_boolean_variables,
        int(CosimVariableType.INTEGER.value): execution.connect_integer_variables,
    }
    for (src, out), (dst, inp) in CONNECTIONS:
        if not connect and src == "conveyor":
            continue
        ref_out, kind = refs[(src, out)]
        connect_by_type[kind](index[src], ref_out, index[dst], refs[(dst, inp)][0])
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    manipulator = CosimManipulator.create_override()
    execution.add_manipulator(manipulator)
    readers = {
        int(CosimVariableType.REAL.value): observer.last_real_values,
        int(CosimVariableType.BOOLEAN.value): observer.last_boolean_values,
        int(CosimVariableType.INTEGER.value): observer.last_integer_values,
    }
    trace: dict[str, list[Any]] = {"time": []}
    trace.update({f"{i}.{v}": [] for i, v in TRACE})
    steps = round(seconds / PERIOD)
    for step in range(steps):
        for at, inst, var in TRIGGERS:
            if at == step:
                manipulator.slave_boolean_values(index[inst], [refs[(inst, var)][0]], [True])
        execution.step()
        trace["time"].append((step + 1) * PERIOD)
        for inst, var in TRACE:
            ref, kind = refs[(inst, var)]
            trace[f"{inst}.{var}"].append(readers[kind](index[inst], [ref])[0])
    execution.stop()
    return trace


SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"


def trigger_input(instance: str, variable: str) -> str:
    """The SSP system's input connector that carries an operator's trigger."""
    return f"{instance}.{variable}".replace(".", "_")


def ssp(fmus: dict[str, Path], dest: Path, connect: bool = True) -> Path:
    """The line as an SSP archive (SSP 1.0) for fmpy's master: the three FMUs under
    ``resources/`` and a ``SystemStructure.ssd`` declaring, per component, the connected
    inputs and the traced outputs (types read from each FMU's model description), one
    system input per operator trigger, and ``CONNECTIONS`` (``connect`` False: without the
    plant's sensor, as :func:`run`).

    Only connected inputs are declared: fmpy 0.3's ``get_connections`` wires an input
    connector that no connection reaches to the previous input's source, silently."""
    from fmpy import read_model_description

    types: dict[tuple[str, str], str] = {}
    for name, fmu in fmus.items():
        for v in read_model_description(str(fmu), validate=False).modelVariables:
            types[(name, v.name)] = v.type
    wired = [c for c in CONNECTIONS if connect or c[0][0] != "conveyor"]
    inputs = {dst for _, dst in wired} | {(i, v) for _, i, v in TRIGGERS}
    outputs = {src for src, _ in wired} | set(TRACE)

    def connector(name: str, kind: str, type_name: str) -> str:
        return (
            f"<ssd:Connector name={quoteattr(name)} kind={quoteattr(kind)}>"
            f"<ssc:{type_name}/></ssd:Connector>"
        )

    def wire(start: str | None, out: str, end: str, inp: str) -> str:
        first = "" if start is None else f"startElement={quoteattr(start)} "
        return (
            f"<ssd:Connection {first}startConnector={quoteattr(out)} "
            f"endElement={quoteattr(end)} endConnector={quoteattr(inp)}/>"
        )

    components = []
    for name in fmus:
        connectors = [connector(v, "input", types[(i, v)]) for i, v in sorted(inputs) if i == name]
        connectors += [
            connector(v, "output", types[(i, v)]) for i, v in sorted(outputs) if i == name
        ]
        components.append(
            f"<ssd:Component name={quoteattr(name)} source={quoteattr(f'resources/{name}.fmu')}"
            ' type="application/x-fmu-sharedlibrary">'
            f"<ssd:Connectors>{''.join(connectors)}</ssd:Connectors></ssd:Component>"
        )
    system_inputs = [connector(trigger_input(i, v), "input", "Boolean") for _, i, v in TRIGGERS]
    connections = [wire(s, o, d, i) for (s, o), (d, i) in wired]
    connections += [wire(None, trigger_input(i, v), i, v) for _, i, v in TRIGGERS]
    ssd = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<ssd:SystemStructureDescription xmlns:ssd="{SSD}" xmlns:ssc="{SSC}" version="1.0"'
        ' name="line">'
        '<ssd:System name="line">'
        f"<ssd:Connectors>{''.join(system_inputs)}</ssd:Connectors>"
        f"<ssd:Elements>{''.join(components)}</ssd:Elements>"
        f"<ssd:Connections>{''.join(connections)}</ssd:Connections>"
        "</ssd:System></ssd:SystemStructureDescription>\n"
    )
    dest.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("SystemStructure.ssd", ssd)
        for name, fmu in fmus.items():
            archive.write(fmu, f"resources/{name}.fmu")
    return dest


def run_fmpy(
    fmus: dict[str, Path], seconds: float = 3.0, connect: bool = True, dest: Path | None = None
) -> dict[str, Any]:
    """Run the line for ``seconds`` under fmpy's SSP master; the trace as :func:`run`'s,
    at the same ticks.

    fmpy's master is, like libcosim's fixed-step algorithm, a Jacobi scheme: every FMU
    steps on its inputs from the previous exchange, then the outputs move to the
    connected inputs. Two things differ, and are squared here, not in fmpy:

    - a system input (an operator's trigger) moves to its FMU in that same exchange,
      after the step: given at ``t`` it reaches the FMU in the step from ``t + h``, where
      libcosim's override reaches the step from ``t``. So the trigger of step ``k`` is
      given from step ``k - 1`` on;
    - the master adds the step to a floating-point time until it reaches ``stop_time``:
      a stop half a step before the last step's start gives exactly the steps wanted,
      whatever the rounding, and the trigger functions count steps by ``round(t / h)``.

    Its rows are labelled with each step's start time; the trace keeps :func:`run`'s
    labels (the step's end)."""
    from fmpy.ssp.simulation import simulate_ssp

    steps = round(seconds / PERIOD)

    def rises_at(at: int) -> Any:
        return lambda time: round(time / PERIOD) >= at - 1

    with tempfile.TemporaryDirectory() as tmp:
        archive = ssp(fmus, (dest or Path(tmp)) / "line.ssp", connect)
        rows = simulate_ssp(
            str(archive),
            stop_time=(steps - 0.5) * PERIOD,
            step_size=PERIOD,
            input={trigger_input(i, v): rises_at(at) for at, i, v in TRIGGERS},
        )
    trace: dict[str, list[Any]] = {"time": [(k + 1) * PERIOD for k in range(len(rows))]}
    trace.update({f"{i}.{v}": rows[f"{i}.{v}"].tolist() for i, v in TRACE})
    return trace


def plot(trace: dict[str, Any], path: Path, master: str = "libcosim") -> None:
    """Belt position, sensor and knife phase against time, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = trace["time"]
    knife, belt = trace["cutter.Knife.CommandPosition"], trace["cutter.Belt.ActualPosition"]
    phase = [k - b for k, b in zip(knife, belt, strict=True)]
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 6.5))
    axes[0].plot(t, trace["infeed.Belt.ActualPosition"], label="belt (infeed controller)")
    axes[0].set_ylabel("position [mm]")
    axes[0].legend(loc="upper left")
    axes[1].step(
        t,
        [float(s) for s in trace["conveyor.sensor"]],
        where="post",
        label="registration sensor (plant)",
    )
    axes[1].step(
        t,
        [0.5 * float(s) for s in trace["cutter.Phase.IP"]],
        where="post",
        label="Phase.IP / 2 (cutter MAM: the correction)",
        linestyle="--",
    )
    axes[1].set_ylabel("bit")
    axes[1].legend(loc="upper left", fontsize="small", framealpha=0.9)
    axes[1].set_ylim(-0.1, 1.6)
    axes[2].plot(t, phase, label="knife phase: command - belt (cutter controller)")
    axes[2].set_ylabel("phase [mm]")
    axes[2].set_xlabel("simulated time [s]")
    axes[2].legend(loc="upper left")
    fig.suptitle(f"Two controller FMUs and a conveyor FMU in lockstep under {master}")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--master", choices=["libcosim", "fmpy"], default="libcosim")
    p.add_argument("--seconds", type=float, default=3.0)
    p.add_argument("--plot", type=Path, help="write the plot (PNG) there")
    p.add_argument("--dir", type=Path, help="build the FMUs there (default: a temporary one)")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        fmus = build(args.dir or Path(tmp))
        if args.master == "fmpy":
            # with --dir, the SSP archive stays there beside the FMUs
            trace = run_fmpy(fmus, args.seconds, dest=args.dir)
        else:
            trace = run(fmus, args.seconds)
    phase = trace["cutter.Knife.CommandPosition"][-1] - trace["cutter.Belt.ActualPosition"][-1]
    print(f"products seen: {trace['conveyor.products'][-1]}, knife phase: {phase:.3f} mm")
    if args.plot:
        plot(trace, args.plot, args.master)
        print(f"plot written to {args.plot}")


if __name__ == "__main__":
    main()
