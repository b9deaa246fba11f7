"""The effects a measured torque-speed envelope can add to the spec sheet's (the registry :data:`EFFECTS`).

The envelope model itself is :mod:`hound_id.mor.envelope`; this registry sits below
:mod:`hound_id.mor.spec` so that a spec's ``envelope:`` section is checked against it without
the spec importing the model. Adding an effect is one entry here and its physics in the model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hound_id.parameter import Parameter

__all__ = ["EFFECTS", "EnvelopeEffect"]


@dataclass(frozen=True)
class EnvelopeEffect:
    """One physical reason for the measured envelope to differ from the spec sheet's."""

    name: str
    physics: str
    """One sentence of physics."""
    param: Parameter
    """Its one parameter: name, unit, physically sensible range (``lower``, ``upper``) and ``neutral`` value."""
    requires: tuple[str, ...] = ()
    """Log channels or inputs it needs: ``temperature``, ``pole_pairs``, ``current_curve`` (a fitted one)."""

    @property
    def parameter(self) -> str:
        """The parameter's name."""
        return self.param.name

    @property
    def unit(self) -> str:
        return self.param.unit

    @property
    def bounds(self) -> tuple[float, float]:
        """Physically sensible range of the parameter."""
        return self.param.lower, self.param.upper

    @property
    def neutral(self) -> float:
        """Value at which the effect does nothing."""
        return float("nan") if self.param.neutral is None else self.param.neutral


EFFECTS: dict[str, EnvelopeEffect] = {
    e.name: e
    for e in sorted(
        [
            EnvelopeEffect(
                "bus_sag",
                "the battery's internal resistance drops the bus voltage under motoring load",
                Parameter("r_pack", "ohm", "the pack's internal resistance", 0.0, 5.0, neutral=0.0),
            ),
            EnvelopeEffect(
                "regen_rise",
                "regenerated current raises the bus voltage while braking",
                Parameter("r_regen", "ohm", "the bus's resistance to regenerated current", 0.0, 5.0, neutral=0.0),
            ),
            EnvelopeEffect(
                "thermal_resistance",
                "the winding's copper resistance grows 0.39 %/K as it heats",
                Parameter("alpha", "1/K", "temperature coefficient of the winding resistance", 0.0, 0.01, neutral=0.0),
                ("temperature",),
            ),
            EnvelopeEffect(
                "inductance",
                "the q-axis current needs p omega L i of voltage in quadrature at speed",
                Parameter("inductance", "H", "q-axis inductance", 0.0, 0.01, neutral=0.0),
                ("pole_pairs",),
            ),
            EnvelopeEffect(
                "current_limit",
                "the driver clamps the current below the spec sheet's limit",
                Parameter("i_limit", "A", "the driver's current limit", 0.0, np.inf, neutral=np.inf),
            ),
            EnvelopeEffect(
                "kt_saturation",
                "the core saturates: torque per amp falls at high current, so each "
                "newton metre costs more current and voltage",
                Parameter(
                    "scale",
                    "-",
                    "share of the fitted current-torque curve's departure from tau/Kt",
                    0.0,
                    2.0,
                    neutral=0.0,
                ),
                ("current_curve",),
            ),
        ],
        key=lambda e: e.name,
    )
}
