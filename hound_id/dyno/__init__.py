"""Dynamometer and robot logs in, identified motor models out.

Data flows one way through the rooms of this package:

* :mod:`~hound_id.dyno.acquire`: record logs from a rig (Modbus, serial), plan a test, a simulated rig;
* :mod:`~hound_id.dyno.logs`: the one reader of both log kinds (columns, units rows, cleaning);
* :mod:`~hound_id.dyno.identify`: the engine both model families share (suggestions, significance, ladder);
* :mod:`~hound_id.dyno.current`: the current-torque family (effects, fit, diagnosis, curve, report, plot);
* :mod:`~hound_id.dyno.envelope`: the torque-speed envelope family (walls, offsets, evidence, ladder, report);
* :mod:`~hound_id.dyno.simulate`: seeded logs with known truth, for tests, samples and benchmarks;
* :mod:`~hound_id.dyno.fleet`: many logs at once on Dask.

Each room's ``run`` module holds its commands' verbs: ``current.run`` (fit-current), ``envelope.run`` (mor
--compare), ``fleet.run`` (fleet), ``acquire.run`` (dyno record, dyno simulate-rig).
"""
