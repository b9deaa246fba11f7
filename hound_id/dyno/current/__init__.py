"""The current-torque model family: effects (regressors with bounded parameters), the fit (block cross-validation),
the diagnosis (which effect is missing), the curve (peak torque, compensation), the report and its plot."""
