"""The core's description of a robot and what was recorded on it: the model records, the
parameters (one table of kinds and units, vector <-> model), the batched kinematic engine,
classic <-> modified DH, measurements and contacts.

May import: ``_base``.
"""
