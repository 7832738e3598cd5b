"""Parameters that choose an arm (built-in DH table or a YAML file), shared by the arm modules.

The table is loaded when the parameters are validated, so a bad DH file is a parameter error
reported by ``umbra check`` before anything starts, and the joint names of the ports
(``joints=from_param("joint_names")``) are known to the checker.
"""

from __future__ import annotations

from typing import Literal

from pydantic import PrivateAttr, field_validator, model_validator

from umbra.connectors import Parameters, param
from umbra.modules.arm.dh import DHError, DHTable, puma560
from umbra.modules.arm.dh_yaml import load_dh_table

BUILT_IN_ARMS = {"puma560": puma560}


def load_arm(robot: str, dh_file: str) -> DHTable:
    """The DH table of ``dh_file`` when given, else of the built-in ``robot``."""
    if dh_file:
        return load_dh_table(dh_file)
    try:
        return BUILT_IN_ARMS[robot]()
    except KeyError:
        raise DHError(f"unknown robot {robot!r}; built in: {sorted(BUILT_IN_ARMS)}") from None


class ArmParams(Parameters):
    """``robot`` / ``dh_file`` and the loaded table (``table``, ``joint_names``)."""

    robot: Literal["puma560"] = param("puma560", "built-in arm, used when dh_file is empty")
    dh_file: str = param("", "YAML DH table (format: modules/arm/dh_yaml.py); overrides robot")

    _table: DHTable = PrivateAttr()

    @field_validator("dh_file")
    @classmethod
    def _dh_file_loads(cls, value: str) -> str:
        if value:
            try:
                load_dh_table(value)
            except DHError as exc:
                raise ValueError(str(exc)) from None
        return value

    @model_validator(mode="after")
    def _load_table(self) -> ArmParams:
        self._table = load_arm(self.robot, self.dh_file)
        return self

    @property
    def table(self) -> DHTable:
        """The arm's DH table."""
        return self._table

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The arm's joint names, in order (what the joint ports carry)."""
        return self._table.names
