"""Files in and out, the only place units are converted (docs/formats.md): model files (YAML),
measurement files (CSV), contact files (CSV), result files (JSON), repeatability files (CSV), URDF, DH tables,
robot programs (ABB RAPID, KUKA KRL, URScript), campaigns recorded as ROS bags (the ``ros`` extra)."""

from ._base import arguments as _arguments
from ._files.bags import BagCampaign, read_bag
from ._files.contacts import contacts_to_csv, read_contacts, write_contacts
from ._files.dh import dh_csv, mdh_csv, read_dh_table, write_mdh_csv
from ._files.measurements import measurements_to_csv, read_measurements, split_sets, write_measurements
from ._files.model import model_from_dict, model_to_dict, model_to_yaml, read_calibration, read_model, write_model
from ._files.profile import Profile, profile_from_dict, read_profile
from ._files.programs import program_joints, read_program, read_program_joints
from ._files.programs.compensation import ProgramCompensation, TargetResult, compensate_program
from ._files.programs.syntax import Program, Target
from ._files.repeatability import read_repeatability_csv
from ._files.result import (
                            limit_to_dict,
                            read_result,
                            result_files,
                            result_from_dict,
                            result_to_dict,
                            result_to_json,
                            write_result,
)
from ._files.stills import Left, StillRules
from ._files.table import ColumnMap
from ._files.text import sidecar_path
from ._files.urdf import read_urdf, urdf_text, write_urdf
from ._identification.result import calibration_record
from ._model.contacts import Contacts, KnownDistance, KnownPlane
from ._model.conversion import StandardDH, from_standard_dh, mdh_table, to_standard_dh
from ._model.measurements import Measurements, Noise

__all__ = ["read_model", "write_model", "calibration_record", "read_calibration", "model_from_dict", "model_to_dict",
           "model_to_yaml",
           "Measurements", "Noise", "Contacts", "KnownDistance", "KnownPlane",
           "read_measurements", "write_measurements", "read_profile", "profile_from_dict",
           "Profile", "ColumnMap", "measurements_to_csv", "split_sets", "read_result",
           "write_result", "result_files", "sidecar_path", "result_from_dict", "result_to_dict", "result_to_json",
           "limit_to_dict",
           "read_repeatability_csv", "read_contacts", "write_contacts", "contacts_to_csv", "read_urdf", "write_urdf",
           "from_standard_dh", "mdh_table", "write_mdh_csv", "urdf_text", "to_standard_dh", "StandardDH", "mdh_csv",
           "dh_csv", "read_dh_table"]
__all__ += ["read_program", "read_program_joints", "program_joints", "compensate_program", "Program", "Target",
            "ProgramCompensation", "TargetResult", "read_bag", "BagCampaign", "StillRules", "Left"]

# the functions users call check their arguments; robocal's own code calls them unchecked
_arguments.export_checked(globals())
