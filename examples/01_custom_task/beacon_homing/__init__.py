"""Beacon homing: an example of a task of one's own for sdbc (see ../README.md)."""

from beacon_homing.task import BeaconHoming, BeaconHomingConfig

__all__ = ["BeaconHoming", "BeaconHomingConfig"]
