"""The image filler does work in proportion to what changed: a tag that only a write (or
the scan itself, when it says so) can change is not read again after every cycle, and
still shows its new value in the image published after the write."""

from __future__ import annotations

from collections import deque

from motion_server import config
from motion_server.image import wire
from motion_server.safety.client import ClientInfo
from motion_server.scan import Scan
from motion_server.scan.channel import MODBUS, Channel
from motion_server.tagmap import Folder

SITE = """
[site]
name = "filler"

[controller]
clock = "manual"
status_log_interval = 0.0

[modbus]
enabled = false

[opcua]
enabled = false

[[groups]]
name = "Group1"
axes = ["Axis1"]

[[axes]]
name = "Axis1"
type = "virtual"

[[watchdogs]]
name = "WD1"
timeout = 0.5
group = "Group1"
"""


class Quiet(Channel):
    """A channel without a socket."""

    def __init__(self) -> None:
        self.number = MODBUS
        self.name = "modbus"
        self.assembler = wire.BatchAssembler()
        self.outbox = deque()
        self.closed = False
        self.welcomed = True
        self.peer_pid = 0

    def receive(self) -> list[bytes]:
        return []

    def send(self, packet: bytes) -> None:
        return None

    def flush(self) -> None:
        return None


def test_written_only_tags_are_not_read_every_cycle_and_show_when_written() -> None:
    scan = Scan(config.parse(SITE, "filler.toml"))
    scan.start(0.0)
    ch = Quiet()
    scan.attach(ch)
    layout = scan.layout
    each = {layout.tags[int(s)].name for s in scan.filler._each_slots}
    written_only = {
        t.name for t in layout.tags if t.writable and t.folder in (Folder.CLOCK, Folder.SAFETY)
    }
    assert {"Clock.Mode", "Clock.StepCycles", "WD1.Heartbeat", "WD1.Reset"} <= written_only
    assert not each & written_only
    assert {"Clock.Cycle", "WD1.State", "WD1.Age"} <= each  # what the scan changes stays
    slot = {t.name: i for i, t in enumerate(layout.tags)}
    client = ClientInfo("modbus", "10.0.0.1")
    items = [(slot["WD1.Heartbeat"], 41.0), (slot["Clock.StepCycles"], 7.0)]
    scan.deliver(ch, wire.Batch(1, client, items))
    scan.cycle(1)
    snap = scan.writer
    values = snap._values[snap.count & 1]
    assert values[slot["WD1.Heartbeat"]] == 41.0
    assert values[slot["Clock.StepCycles"]] == 7.0
