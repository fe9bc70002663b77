"""Tests of roughsense.io, beside its modules' paths."""
