from services.msgs import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class PlantFlightRequest(_message.Message):
    __slots__ = ("header", "after_ms")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    AFTER_MS_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    after_ms: int
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., after_ms: _Optional[int] = ...) -> None: ...

class PlantFlight(_message.Message):
    __slots__ = ("header", "time_ms", "position", "velocity_mps", "path_m", "planned_m", "flights", "dim", "altitude_m", "velocity_up_mps")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    TIME_MS_FIELD_NUMBER: _ClassVar[int]
    POSITION_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_MPS_FIELD_NUMBER: _ClassVar[int]
    PATH_M_FIELD_NUMBER: _ClassVar[int]
    PLANNED_M_FIELD_NUMBER: _ClassVar[int]
    FLIGHTS_FIELD_NUMBER: _ClassVar[int]
    DIM_FIELD_NUMBER: _ClassVar[int]
    ALTITUDE_M_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_UP_MPS_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    time_ms: int
    position: _common_pb2.Vec2
    velocity_mps: _common_pb2.Vec2
    path_m: _containers.RepeatedScalarFieldContainer[float]
    planned_m: _containers.RepeatedScalarFieldContainer[float]
    flights: int
    dim: int
    altitude_m: float
    velocity_up_mps: float
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., time_ms: _Optional[int] = ..., position: _Optional[_Union[_common_pb2.Vec2, _Mapping]] = ..., velocity_mps: _Optional[_Union[_common_pb2.Vec2, _Mapping]] = ..., path_m: _Optional[_Iterable[float]] = ..., planned_m: _Optional[_Iterable[float]] = ..., flights: _Optional[int] = ..., dim: _Optional[int] = ..., altitude_m: _Optional[float] = ..., velocity_up_mps: _Optional[float] = ...) -> None: ...
