"""Foot geometry, mass properties, leg model and foot optimisation."""
