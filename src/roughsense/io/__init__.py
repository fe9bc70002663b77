"""The study folder contract: read, validate and write study folders, their tables and their images.

Every source (the twin, the rig) writes through here and the analysis reads through here; nothing above re-validates.
"""
