"""Tests of roughsense.sensor, beside its modules' paths."""
