"""``motion-server check`` of large site maps: 1,000, 4,000 and 10,000 axes.

Each map declares N virtual axes in one group with the default register bases, as a
site that simply lists many axes would: from about 1,290 axes on, the axis blocks pass
register 65535, so every further axis is a problem to report (the case that grew
quadratically: 4,000 axes took 25.6 s). The largest map the Modbus layout holds
(1,200 axes, ``axis_base = 4000``) is checked too and accepted.

Each case is timed side by side with the bare TOML parse of the same text
(``tomllib.loads``, which any check must do): the ratio check / parse stays flat when
check is linear in the size of the map, and grows with N when it is not. The check is
what ``motion-server check`` runs: load (schema, cross-field checks, register layout,
access rules), then assemble (controller, instruction instances, tag map, watchdogs,
users, and the probes of directories and ports).

    python bench/config_check.py [--sizes 1000 4000 10000]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import tomllib
from pathlib import Path

from motion_server import config
from motion_server.config.assembly import assemble

TARGET_SECONDS = 10.0  # check of 10,000 axes


def site_text(axes: int, axis_base: int = 1000) -> str:
    lines = [
        f"[modbus]\nport = 0\naxis_base = {axis_base}\n",
        "[opcua]\nport = 0\ndata_dir = 'opcua-data'\n",
    ]
    for i in range(axes):
        lines.append(
            f'[[axes]]\nname = "Axis{i + 1}"\ntype = "virtual"\nmax_velocity = 500.0\n'
            "max_acceleration = 5000.0\nmax_deceleration = 5000.0\n"
        )
    names = ", ".join(f'"Axis{i + 1}"' for i in range(axes))
    lines.append(f'[[groups]]\nname = "Group1"\naxes = [{names}]\n')
    return "\n".join(lines)


def check(path: Path) -> str:
    try:
        assembly = assemble(config.load(path, environ={}), environ={})
    except config.SiteMapError as exc:
        lines = str(exc).splitlines()
        return f"refused, {len(lines)} lines shown ({lines[-1].split(': ', 1)[-1]})"
    return f"accepted, {len(assembly.system.ctl.axes)} axes, {len(assembly.tagmap)} tags"


def timed(action: object) -> tuple[float, float, object]:
    w0, c0 = time.perf_counter(), time.process_time()
    result = action()  # type: ignore[operator]
    return time.perf_counter() - w0, time.process_time() - c0, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 4000, 10000])
    args = parser.parse_args()
    cases = [(n, 1000) for n in args.sizes] + [(1200, 4000)]
    print(f"load average {os.getloadavg()[0]:.2f}")
    print(f"{'axes':>6} {'base':>5} {'toml s':>8} {'check s':>8} {'check cpu s':>11} "
          f"{'ratio':>6}  result")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)
        for n, base in cases:
            text = site_text(n, base)
            path = Path(tmp) / f"axes{n}.toml"
            path.write_text(text)
            parse_s, _, _ = timed(lambda text=text: tomllib.loads(text))
            wall, cpu, result = timed(lambda path=path: check(path))
            print(f"{n:>6} {base:>5} {parse_s:>8.3f} {wall:>8.3f} {cpu:>11.3f} "
                  f"{wall / parse_s:>6.1f}  {result}")  # fmt: skip
            if n == 10000:
                verdict = "met" if wall <= TARGET_SECONDS else "MISSED"
                target = f"target {TARGET_SECONDS:.0f} s {verdict}"
                print(f"       10,000 axes in {wall:.2f} s: {target}")


if __name__ == "__main__":
    main()
