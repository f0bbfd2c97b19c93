"""The algorithm core: pure functions of arrays and parameter objects, packaged along the paper's pipeline.

No I/O, no storage, no web: the services, jobs and CLI call these with plain data. The packages, from the
bottom layer up (``pyproject.toml`` holds the import-linter contract that keeps them so):

- :mod:`~driftmap.core.imaging` (image pre-processing, shifted SAD, shift registration) and
  :mod:`~driftmap.core.graph` (the pose graph and its solve);
- :mod:`~driftmap.core.odometry` (ground-plane visual odometry), :mod:`~driftmap.core.loop_closure`
  (appearance-only loop closure) and :mod:`~driftmap.core.sesame` (saliency masks, the glare classifier);
- :mod:`~driftmap.core.topomap` (map compression into places and their reference frames);
- :mod:`~driftmap.core.localisation` (the online HMM localiser) and :mod:`~driftmap.core.mapping` (the
  whole mapping pipeline);
- :mod:`~driftmap.core.place_recognition` (place recognition on outside datasets, metrics).

:mod:`driftmap.core.types` holds the shared array aliases (``F64``, ``F32``, ``I64``, ...) and the one
progress callback, ``ProgressFn = (stage, fraction) -> None``.

Parameters are frozen dataclasses next to the code that uses them; presets are module constants named
``<STAGE>_PAPER`` (as close to the papers as they say), ``<STAGE>_DEFAULT`` (what driftmap uses) and
``<STAGE>_FAST`` (accuracy traded for speed), e.g. ``ODOMETRY_FAST`` or ``LOOPS_PAPER``; a stage may add
named variants (``ODOMETRY_LIVE``, ``ROUTE_ONLINE``).

Errors follow one rule. Input a caller can get wrong (an array of the wrong shape or dtype, a parameter
out of range, a frame that does not exist) raises :class:`driftmap.errors.BadInputError` naming the field
at fault, which the API answers with 422 and the CLI prints without a traceback. A broken invariant of the
code itself (inconsistent internal state, a caller inside driftmap breaking a contract) raises
``ValueError`` or fails an ``assert``: that is a bug, not bad input.
"""
