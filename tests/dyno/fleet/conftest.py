"""Fixtures of the fleet tests."""

import logging

import pytest


@pytest.fixture(scope="module")
def cluster():
    """A local Dask cluster of two worker processes, one per module that uses it."""
    from dask.distributed import LocalCluster

    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
    ) as c:
        yield c
