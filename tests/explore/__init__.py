"""Tests of roughsense.explore, beside its modules' paths."""
