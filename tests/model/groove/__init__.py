"""Tests of roughsense.model.groove, beside its modules' paths."""
