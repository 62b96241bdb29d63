"""Foundations every folder uses: errors and warnings, argument checks of the public face,
option values, units, read-only arrays, elementary rotations, BLAS threads, R factors.

May import: nothing of robocal (numpy and scipy only where a module needs them).
"""
