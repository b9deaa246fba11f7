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


def typed_report(model, parameters, *, peak=None, noise_floor=0.015, at_noise_floor=True, summary="", suggestions=()):
    """A :class:`~hound_id.dyno.current.fit_report.FitReport` with the given model, parameters and verdict, the rest
    neutral (no blocks, no ladder, nothing cleaned): what the fleet's analysis reads, set by a test."""
    from hound_id.dyno.current.curve import PeakTorque
    from hound_id.dyno.current.fit_report import FitReport, Rows

    return FitReport(
        source="x.csv",
        model=tuple(model),
        parameters=dict(parameters),
        rmse_train=noise_floor,
        rmse_test=noise_floor,
        rmse_outside_flagged=None,
        blocks=(),
        aic=0.0,
        bic=0.0,
        robust=False,
        rows=Rows(None, 0, 0, 0),
        unphysical={},
        flags=(),
        peak=peak if peak is not None else PeakTorque(None, None, 0.0, False, ""),
        curve=None,
        polynomial=None,
        suggestions=tuple(suggestions),
        skipped=(),
        outliers=None,
        noise_floor=noise_floor,
        noise=None,
        wander=None,
        wander_said=None,
        at_noise_floor=at_noise_floor,
        summary=summary,
        ladder=None,
        cleaning=(),
    )
