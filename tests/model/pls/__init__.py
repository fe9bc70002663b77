"""Tests of roughsense.model.pls, beside its modules' paths."""
