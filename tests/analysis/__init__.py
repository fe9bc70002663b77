"""Tests of roughsense.analysis, beside its modules' paths."""
