"""Tests of roughsense.model.peak_law, beside its modules' paths."""
