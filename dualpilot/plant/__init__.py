"""The plant: what flies between planning steps (Eq. (1) exactly, or a multirotor in wind).

The planners keep Eq. (1) as their model and never import this package.
"""

from dualpilot.plant.params import AirframeParams, ControllerParams, MultirotorParams
from dualpilot.plant.plant import (
    Flight,
    IdealPlant,
    MultirotorPlant,
    Plant,
    PlantKind,
    PlantParams,
    make_plant,
)
from dualpilot.plant.sensors import GpsParams
from dualpilot.plant.wind import GustParams, WindParams

__all__ = [
    "AirframeParams", "ControllerParams", "Flight", "GpsParams", "GustParams", "IdealPlant",
    "MultirotorParams", "MultirotorPlant", "Plant", "PlantKind", "PlantParams", "WindParams",
    "make_plant",
]
