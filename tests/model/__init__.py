"""Tests of roughsense.model, beside its modules' paths."""
