"""The controller as an FMI Co-Simulation FMU (docs/co-simulation.md).

- :mod:`.variables`: the FMU's variables, from the tag map (inputs, outputs, parameters);
- :mod:`.engine`: the scan in-process, stepped by the master (no FMI builder needed);
- :mod:`.serving`: ``--serve``, the front-ends on the image while the master steps;
- :mod:`.shipped`: the files the FMU carries beside its script (the site map);
- :mod:`.slave2`, :mod:`.slave3`: the scripts inside the FMU (pythonfmu, pythonfmu3);
- :mod:`.build`: ``motion-server fmu``, which packs them with the builders.
"""
