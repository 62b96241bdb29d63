"""Simulation before the robot is touched: a perturbed "true" robot and its measurements; campaigns
of a real robot with what a model may leave out (``RobotImperfections``: encoder counts, lost motion,
gear errors, elasticity, drift, scatter, instrument noise) and its accuracy in use; joint-only
campaigns of sockets, planes and ball bars, and the planning of a socket campaign."""

from ._base import arguments as _arguments
from ._model.configurations import random_configurations
from ._model.measurements import approach_sides
from ._simulation.campaign import (
    PRESETS,
    RobotImperfections,
    accuracy_in_use,
    attained,
    backlash_sides,
    measure_campaign,
    placement_errors,
    stored_model,
)
from ._simulation.contacts import bar_campaign, plane_campaign, plate_placements, reach, socket_campaign
from ._simulation.poses import CampaignPrediction, PoseSelection, predict_campaign, select_poses
from ._simulation.simulate import measure, perturb_model, simulate
from ._simulation.sockets import SocketDesign, SocketPlan, plan_sockets

__all__ = ["simulate", "measure", "perturb_model", "random_configurations", "RobotImperfections",
           "measure_campaign", "accuracy_in_use", "approach_sides", "backlash_sides", "stored_model",
           "socket_campaign", "plane_campaign", "bar_campaign", "plate_placements", "reach", "plan_sockets",
           "SocketPlan", "SocketDesign", "PRESETS", "attained", "placement_errors", "select_poses", "PoseSelection",
           "predict_campaign", "CampaignPrediction"]

# the functions users call check their arguments; robocal's own code calls them unchecked
_arguments.export_checked(globals())
