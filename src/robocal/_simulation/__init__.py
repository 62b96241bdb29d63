"""Before the robot is touched: simulated robots and campaigns (with effects beyond the model),
simulated contact campaigns, and planning (pose selection, socket-plate campaigns).

May import: ``_base``, ``_model``, ``_identification``, ``_accuracy``.
"""
