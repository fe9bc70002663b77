"""The paper's analysis of a study folder: targets from ratings, cross-validated models, metrics, controls, claims.

It never knows whether a folder was simulated or captured; it returns tables that report/ renders.
"""
