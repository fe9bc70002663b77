"""Plumbing with no knowledge of roughness: atomic writes, the cache, worker processes, parameter checks.

Everything may import it; it imports nothing of roughsense but ``errors``.
"""
