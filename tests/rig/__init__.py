"""Tests of roughsense.rig, beside its modules' paths."""
