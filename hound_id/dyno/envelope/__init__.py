"""The torque-speed envelope family: which samples sit at the limit (walls), how far they sit from a model (offsets),
what logged channels show (evidence), the add-an-effect ladder (compare), its JSON and spec file (report), its plot.
The envelope model itself lives in :mod:`hound_id.mor.envelope`."""
