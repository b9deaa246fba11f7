"""Many actuators at once: fit every log with one model on Dask and compare the fleet (``hound-id fleet``)."""
