"""The model layer: a URDF document, its named parameters, and structural edits."""

from .authoring import find_joint_between, insert_parasitic_joint, move_pivot
from .document import UrdfDocument
from .joint_elements import Spring, Transmission
from .parameters import (
    GROUPS,
    ParameterInfo,
    get_parameter,
    get_parameters,
    group_members,
    link_inertial,
    parameter_infos,
    parameter_names,
    select_parameters,
    set_link_inertial,
    set_parameter,
    set_parameters,
)

__all__ = [
    "GROUPS",
    "ParameterInfo",
    "Spring",
    "Transmission",
    "UrdfDocument",
    "find_joint_between",
    "get_parameter",
    "get_parameters",
    "group_members",
    "insert_parasitic_joint",
    "link_inertial",
    "move_pivot",
    "parameter_infos",
    "parameter_names",
    "select_parameters",
    "set_link_inertial",
    "set_parameter",
    "set_parameters",
]
