"""Safety and hardening around the tag image: who is writing (:mod:`.client`), the
communication watchdogs (:mod:`.watchdog`), the audit log (:mod:`.audit`), Modbus access
control (:mod:`.access`) and retentive memory (:mod:`.retain`).

Nothing here runs inside the kernel: the runtime calls the watchdogs before every cycle,
the front-ends set the current client around each request, and the tag image reports
accepted writes to its observers (the audit log).
"""

from .client import ClientInfo, current_client, writing_as

__all__ = ["ClientInfo", "current_client", "writing_as"]
