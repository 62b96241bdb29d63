"""Simulation before the robot is touched: a perturbed "true" robot and its measurements, and
campaigns with a real robot's imperfections (encoder counts, scatter, instrument noise, lost motion);
joint-only campaigns of sockets, planes and ball bars, and the planning of a socket campaign; robots with
effects beyond the model (elasticity, gear errors, drift, scatter) and their accuracy in use."""

from ._base import arguments as _arguments
from ._model.configurations import random_configurations
from ._model.measurements import approach_sides
from ._simulation.campaign import RobotImperfections, accuracy_in_use, backlash_sides, measure_campaign, stored_model
from ._simulation.contacts import bar_campaign, plane_campaign, plate_placements, reach, socket_campaign
from ._simulation.effects import PRESETS, UnmodelledEffects, attained, measure_real, placement_errors
from ._simulation.poses import CampaignPrediction, PoseSelection, predict_campaign, select_poses
from ._simulation.simulate import measure, perturb_model, simulate
from ._simulation.sockets import SocketDesign, SocketPlan, plan_sockets

__all__ = ["simulate", "measure", "perturb_model", "random_configurations", "RobotImperfections",
           "measure_campaign", "accuracy_in_use", "approach_sides", "backlash_sides", "stored_model",
           "socket_campaign", "plane_campaign", "bar_campaign", "plate_placements", "reach", "plan_sockets",
           "SocketPlan", "SocketDesign", "UnmodelledEffects", "PRESETS", "attained", "measure_real",
           "placement_errors", "select_poses", "PoseSelection", "predict_campaign", "CampaignPrediction"]

# the functions users call check their arguments; robocal's own code calls them unchecked
_arguments.export_checked(globals())
