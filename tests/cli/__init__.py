"""Tests of roughsense.cli, beside its modules' paths."""
