"""A cycle imports nothing: a module loaded the first time a path runs would load inside
a motion cycle. numpy 2 loads some of its submodules on first use (``np.setdiff1d``
loads ``numpy.ma``: about 10 ms, which made the cycle of the first jog and move admitted
together 9 ms late). Run in a fresh interpreter, where nothing else loaded them."""

from __future__ import annotations

import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent(
    """
    import sys
    from motion_server import config

    axes = "".join(
        f'[[axes]]\\nname = "Axis{k}"\\ntype = "virtual"\\nmax_velocity = 2000.0\\n'
        'max_acceleration = 10000.0\\nmax_deceleration = 10000.0\\n'
        for k in range(1, 9)
    )
    text = (
        '[site]\\nname = "imports"\\n[controller]\\nclock = "manual"\\n'
        '[opcua]\\nenabled = false\\n'
        '[[groups]]\\nname = "Group1"\\ncoarse_update_period_ms = 1.0\\naxes = ['
        + ", ".join(f'"Axis{k}"' for k in range(1, 9)) + ']\\n' + axes
        + '[instructions]\\nevery_type = false\\n'
        '[[instructions.instances]]\\nname = "MSO_ALL"\\ntype = "MSO"\\n'
        '[[instructions.instances]]\\nname = "MAJ_1"\\ntype = "MAJ"\\n'
        'operands = { Axis = 1, Speed = 20.0, AccelRate = 1000.0, DecelRate = 1000.0 }\\n'
        '[[instructions.instances]]\\nname = "MAM_1"\\ntype = "MAM"\\n'
        'operands = { Axis = 5, Position = 5.0, MoveType = 1, Speed = 50.0, '
        'AccelRate = 1000.0, DecelRate = 1000.0 }\\n'
    )
    system = config.parse(text, "imports.toml").build()

    def fire(*names):
        for level in (True, False):
            for name in names:
                system[name].inputs["Execute"] = level
            system.cycle(1)

    mso = system["MSO_ALL"]
    for k in range(1, 9):
        mso.inputs["Axis"] = k
        fire("MSO_ALL")
    fire("MAJ_1")
    system.cycle(50)  # jogging at 20 mm/s
    before = set(sys.modules)
    system["MAJ_1"].inputs["Speed"] = 50.0
    # in one scan: a jog from motion (planned in the lane) and a move (planned at once)
    # join the profile lane together
    fire("MAJ_1", "MAM_1")
    system.cycle(100)
    for name in ("MAJ_1", "MAM_1"):
        assert system[name].outputs["DN"], name
    print(" ".join(sorted(set(sys.modules) - before)))
    """
)


def test_a_jog_and_a_move_admitted_together_import_nothing() -> None:
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.split() == []
