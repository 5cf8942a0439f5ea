"""The scan: the motion cycle, in a process of its own that imports no protocol code.

:class:`~.core.Scan` is the cycle and its clock; :mod:`.process` runs it as the server's
scan process (``python -m motion_server.scan``, started by the supervisor).
"""

from .core import Scan

__all__ = ["Scan"]
