"""MAH, Motion Axis Home: the homing the axis's configuration describes.

The axis's ``home_mode``, ``home_sequence``, ``home_direction``, speeds and rates (site
map, Logix axis attributes) select the homing (:mod:`motion_server.kernel.homing`):

- immediate (active or passive) and absolute homing: the actual position becomes the
  home position at once (DN and PC in the scan of the rising edge);
- passive homing: DN at once, IP until the home event (a switch edge or a marker the
  axis passes, moved by something else), then PC;
- active homing: DN at once, IP while the sequence runs (HomingStatus, PLCopen state
  Homing), PC when it ends on the home position. A unidirectional sequence whose home
  offset is shorter than the stopping distance ends short of it: IP clears without PC
  (MOTION-RM003). A stop (MAS Home or All, MGS) ends it without PC.

Preconditions: active homing needs Servo Control (ERR 5; a feedback-only axis: ERR 8)
and no stop in progress (ERR 78); absolute homing needs Axis Ready (ERR 4); all modes
refuse a faulted (ERR 20) or shut down (ERR 7) axis. A sequence the axis cannot run (no
home switch or marker configured where the sequence needs one) gives ERR 13.
"""

from __future__ import annotations

from ...kernel import ProcessState
from ...kernel.homing import HomeHandle, configured
from ..base import LogixInstruction
from ..operands import AXIS
from ..registry import register


@register
class MAH(LogixInstruction):
    TYPE = "MAH"
    DESCRIPTION = "Motion Axis Home (the axis's configured homing)"
    OPERANDS = (AXIS,)

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.handle: HomeHandle | None = None

    def execute(self) -> None:
        ax = self.axis()
        self.handle = self.ctl.home(ax, configured(ax), owner=self)
        if self.handle is None:
            self.set_bits(DN=True, IP=False, PC=True)
        else:
            self.set_bits(DN=True, IP=True, PC=False)

    def poll(self) -> None:
        h = self.handle
        if h is None or h.state == ProcessState.ACTIVE:
            return
        if h.state == ProcessState.DONE:
            self.set_bits(IP=False, PC=h.at_home)
        elif h.state == ProcessState.ERROR:
            self.outputs["ERR"] = h.error_code
            self.set_bits(IP=False, ER=True)
        else:
            self.set_bits(IP=False)
        self.handle = None
