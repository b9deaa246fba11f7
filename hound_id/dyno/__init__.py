"""Dynamometer logs in, fitted motor models out (acquisition, effects, fitting, diagnosis)."""
