"""Parameter bundles and simulator/trainer formats."""
