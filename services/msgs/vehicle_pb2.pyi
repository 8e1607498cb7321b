from services.msgs import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class VehicleState(_message.Message):
    __slots__ = ("header", "step", "east_m", "north_m", "velocity_east_mps", "velocity_north_mps", "altitude_m", "velocity_up_mps", "dim")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    STEP_FIELD_NUMBER: _ClassVar[int]
    EAST_M_FIELD_NUMBER: _ClassVar[int]
    NORTH_M_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_EAST_MPS_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_NORTH_MPS_FIELD_NUMBER: _ClassVar[int]
    ALTITUDE_M_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_UP_MPS_FIELD_NUMBER: _ClassVar[int]
    DIM_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    step: int
    east_m: float
    north_m: float
    velocity_east_mps: float
    velocity_north_mps: float
    altitude_m: float
    velocity_up_mps: float
    dim: int
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., step: _Optional[int] = ..., east_m: _Optional[float] = ..., north_m: _Optional[float] = ..., velocity_east_mps: _Optional[float] = ..., velocity_north_mps: _Optional[float] = ..., altitude_m: _Optional[float] = ..., velocity_up_mps: _Optional[float] = ..., dim: _Optional[int] = ...) -> None: ...

class OperatorWaypoints(_message.Message):
    __slots__ = ("header", "waypoints", "mission_id", "revision")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    WAYPOINTS_FIELD_NUMBER: _ClassVar[int]
    MISSION_ID_FIELD_NUMBER: _ClassVar[int]
    REVISION_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    waypoints: _containers.RepeatedCompositeFieldContainer[_common_pb2.Vec2]
    mission_id: str
    revision: int
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., waypoints: _Optional[_Iterable[_Union[_common_pb2.Vec2, _Mapping]]] = ..., mission_id: _Optional[str] = ..., revision: _Optional[int] = ...) -> None: ...
