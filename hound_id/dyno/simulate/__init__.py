"""Seeded log simulators with known truth: current-torque dyno logs (:mod:`.current`) and torque-speed logs driven
past the envelope (:mod:`.envelope`). The independent second simulators used to test identification live in tests/
on purpose (tests/dyno/acquire/polledrig.py, tests/dyno/envelope/holdrig.py): they share no code with these."""
