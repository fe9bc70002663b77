"""Tests of roughsense._util, beside its modules' paths."""
