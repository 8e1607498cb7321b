from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class ErrorCode(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    ERROR_CODE_UNSPECIFIED: _ClassVar[ErrorCode]
    ERROR_CODE_MALFORMED: _ClassVar[ErrorCode]
    ERROR_CODE_INVALID: _ClassVar[ErrorCode]
    ERROR_CODE_INTERNAL: _ClassVar[ErrorCode]
    ERROR_CODE_UNPREPARED: _ClassVar[ErrorCode]
    ERROR_CODE_UNAVAILABLE: _ClassVar[ErrorCode]
ERROR_CODE_UNSPECIFIED: ErrorCode
ERROR_CODE_MALFORMED: ErrorCode
ERROR_CODE_INVALID: ErrorCode
ERROR_CODE_INTERNAL: ErrorCode
ERROR_CODE_UNPREPARED: ErrorCode
ERROR_CODE_UNAVAILABLE: ErrorCode

class Header(_message.Message):
    __slots__ = ("schema_version", "seq", "source", "vehicle_id", "sim_time_s", "wall_time_ns")
    SCHEMA_VERSION_FIELD_NUMBER: _ClassVar[int]
    SEQ_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FIELD_NUMBER: _ClassVar[int]
    VEHICLE_ID_FIELD_NUMBER: _ClassVar[int]
    SIM_TIME_S_FIELD_NUMBER: _ClassVar[int]
    WALL_TIME_NS_FIELD_NUMBER: _ClassVar[int]
    schema_version: int
    seq: int
    source: str
    vehicle_id: str
    sim_time_s: float
    wall_time_ns: int
    def __init__(self, schema_version: _Optional[int] = ..., seq: _Optional[int] = ..., source: _Optional[str] = ..., vehicle_id: _Optional[str] = ..., sim_time_s: _Optional[float] = ..., wall_time_ns: _Optional[int] = ...) -> None: ...

class Vec2(_message.Message):
    __slots__ = ("east_m", "north_m")
    EAST_M_FIELD_NUMBER: _ClassVar[int]
    NORTH_M_FIELD_NUMBER: _ClassVar[int]
    east_m: float
    north_m: float
    def __init__(self, east_m: _Optional[float] = ..., north_m: _Optional[float] = ...) -> None: ...

class Force2(_message.Message):
    __slots__ = ("east_n", "north_n", "up_n")
    EAST_N_FIELD_NUMBER: _ClassVar[int]
    NORTH_N_FIELD_NUMBER: _ClassVar[int]
    UP_N_FIELD_NUMBER: _ClassVar[int]
    east_n: float
    north_n: float
    up_n: float
    def __init__(self, east_n: _Optional[float] = ..., north_n: _Optional[float] = ..., up_n: _Optional[float] = ...) -> None: ...

class Rect(_message.Message):
    __slots__ = ("center_east_m", "center_north_m", "width_m", "height_m")
    CENTER_EAST_M_FIELD_NUMBER: _ClassVar[int]
    CENTER_NORTH_M_FIELD_NUMBER: _ClassVar[int]
    WIDTH_M_FIELD_NUMBER: _ClassVar[int]
    HEIGHT_M_FIELD_NUMBER: _ClassVar[int]
    center_east_m: float
    center_north_m: float
    width_m: float
    height_m: float
    def __init__(self, center_east_m: _Optional[float] = ..., center_north_m: _Optional[float] = ..., width_m: _Optional[float] = ..., height_m: _Optional[float] = ...) -> None: ...

class Polygon(_message.Message):
    __slots__ = ("vertices_m",)
    VERTICES_M_FIELD_NUMBER: _ClassVar[int]
    vertices_m: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, vertices_m: _Optional[_Iterable[float]] = ...) -> None: ...

class Clock(_message.Message):
    __slots__ = ("header", "sim_time_s", "speed_factor", "anchor_wall_ns")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    SIM_TIME_S_FIELD_NUMBER: _ClassVar[int]
    SPEED_FACTOR_FIELD_NUMBER: _ClassVar[int]
    ANCHOR_WALL_NS_FIELD_NUMBER: _ClassVar[int]
    header: Header
    sim_time_s: float
    speed_factor: float
    anchor_wall_ns: int
    def __init__(self, header: _Optional[_Union[Header, _Mapping]] = ..., sim_time_s: _Optional[float] = ..., speed_factor: _Optional[float] = ..., anchor_wall_ns: _Optional[int] = ...) -> None: ...

class Error(_message.Message):
    __slots__ = ("header", "code", "message")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    CODE_FIELD_NUMBER: _ClassVar[int]
    MESSAGE_FIELD_NUMBER: _ClassVar[int]
    header: Header
    code: ErrorCode
    message: str
    def __init__(self, header: _Optional[_Union[Header, _Mapping]] = ..., code: _Optional[_Union[ErrorCode, str]] = ..., message: _Optional[str] = ...) -> None: ...
