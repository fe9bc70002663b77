"""Tests of roughsense.report, beside its modules' paths."""
