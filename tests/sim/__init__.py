"""Tests of roughsense.sim, beside its modules' paths."""
