"""The image: what the scan and the front-ends share, and nothing else.

The scan (its own process, :mod:`motion_server.scan`) and the front-ends (Modbus TCP,
OPC UA: processes of their own) meet in two places only:

- the **image** (:mod:`.buffer`): every tag's value as of the last completed cycle, one
  float64 slot per tag (:mod:`.layout`), in shared memory; the scan writes a whole
  snapshot after every cycle, a front-end copies a consistent one whenever it serves a
  request (two buffers under sequence counters: a reader never sees half a cycle and
  never makes the scan wait);
- the **write queue** (:mod:`.wire`): client writes, already judged by the front-end
  (:mod:`.judge`: type, range, access, and the kernel's numeric limits), sent as
  packets that the scan applies at the start of its next cycle in arrival order and
  acknowledges.

Nothing here imports a protocol stack, asyncio or the kernel.
"""
