"""The effects a measured torque-speed envelope can add to the spec sheet's (the registry :data:`EFFECTS`).

The envelope model itself is :mod:`hound_id.mor.envelope`; this registry sits below
:mod:`hound_id.mor.spec` so that a spec's ``envelope:`` section is checked against it without
the spec importing the model. Adding an effect is one entry here and its physics in the model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["EFFECTS", "EnvelopeEffect"]


@dataclass(frozen=True)
class EnvelopeEffect:
    """One physical reason for the measured envelope to differ from the spec sheet's."""

    name: str
    physics: str
    """One sentence of physics."""
    parameter: str
    unit: str
    bounds: tuple[float, float]
    """Physically sensible range of the parameter."""
    neutral: float
    """Value at which the effect does nothing."""
    requires: tuple[str, ...] = ()
    """Log channels or inputs it needs: ``temperature``, ``pole_pairs``, ``compensation``."""


EFFECTS: dict[str, EnvelopeEffect] = {
    e.name: e
    for e in sorted(
        [
            EnvelopeEffect(
                "bus_sag",
                "the battery's internal resistance drops the bus voltage under motoring load",
                "r_pack",
                "ohm",
                (0.0, 5.0),
                0.0,
            ),
            EnvelopeEffect(
                "regen_rise",
                "regenerated current raises the bus voltage while braking",
                "r_regen",
                "ohm",
                (0.0, 5.0),
                0.0,
            ),
            EnvelopeEffect(
                "thermal_resistance",
                "the winding's copper resistance grows 0.39 %/K as it heats",
                "alpha",
                "1/K",
                (0.0, 0.01),
                0.0,
                ("temperature",),
            ),
            EnvelopeEffect(
                "inductance",
                "the q-axis current needs p omega L i of voltage in quadrature at speed",
                "inductance",
                "H",
                (0.0, 0.01),
                0.0,
                ("pole_pairs",),
            ),
            EnvelopeEffect(
                "current_limit",
                "the driver clamps the current below the spec sheet's limit",
                "i_limit",
                "A",
                (0.0, np.inf),
                np.inf,
            ),
            EnvelopeEffect(
                "kt_saturation",
                "the core saturates: torque per amp falls at high current, so each "
                "newton metre costs more current and voltage",
                "scale",
                "-",
                (0.0, 2.0),
                0.0,
                ("compensation",),
            ),
        ],  # fmt: skip
        key=lambda e: e.name,
    )
}
