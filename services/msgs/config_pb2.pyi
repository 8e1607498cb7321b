from services.msgs import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class ControllerKind(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    CONTROLLER_KIND_UNSPECIFIED: _ClassVar[ControllerKind]
    CONTROLLER_KIND_CC: _ClassVar[ControllerKind]
    CONTROLLER_KIND_S1: _ClassVar[ControllerKind]
    CONTROLLER_KIND_S2: _ClassVar[ControllerKind]

class Timing(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    TIMING_UNSPECIFIED: _ClassVar[Timing]
    TIMING_PAPER: _ClassVar[Timing]
    TIMING_MEASURED: _ClassVar[Timing]
CONTROLLER_KIND_UNSPECIFIED: ControllerKind
CONTROLLER_KIND_CC: ControllerKind
CONTROLLER_KIND_S1: ControllerKind
CONTROLLER_KIND_S2: ControllerKind
TIMING_UNSPECIFIED: Timing
TIMING_PAPER: Timing
TIMING_MEASURED: Timing

class Setting(_message.Message):
    __slots__ = ("name", "value")
    NAME_FIELD_NUMBER: _ClassVar[int]
    VALUE_FIELD_NUMBER: _ClassVar[int]
    name: str
    value: str
    def __init__(self, name: _Optional[str] = ..., value: _Optional[str] = ...) -> None: ...

class RiskParams(_message.Message):
    __slots__ = ("alpha",)
    ALPHA_FIELD_NUMBER: _ClassVar[int]
    alpha: float
    def __init__(self, alpha: _Optional[float] = ...) -> None: ...

class ConcurrentParams(_message.Message):
    __slots__ = ("threat_margin_m", "check_steps", "reanchor_tol_m", "reanchor_tol_mps", "max_wait_hazard", "q_rate", "switch_margin", "energy_scale_n2", "risk", "s2_unavailable", "reanchor_tol")
    THREAT_MARGIN_M_FIELD_NUMBER: _ClassVar[int]
    CHECK_STEPS_FIELD_NUMBER: _ClassVar[int]
    REANCHOR_TOL_M_FIELD_NUMBER: _ClassVar[int]
    REANCHOR_TOL_MPS_FIELD_NUMBER: _ClassVar[int]
    MAX_WAIT_HAZARD_FIELD_NUMBER: _ClassVar[int]
    Q_RATE_FIELD_NUMBER: _ClassVar[int]
    SWITCH_MARGIN_FIELD_NUMBER: _ClassVar[int]
    ENERGY_SCALE_N2_FIELD_NUMBER: _ClassVar[int]
    RISK_FIELD_NUMBER: _ClassVar[int]
    S2_UNAVAILABLE_FIELD_NUMBER: _ClassVar[int]
    REANCHOR_TOL_FIELD_NUMBER: _ClassVar[int]
    threat_margin_m: float
    check_steps: int
    reanchor_tol_m: float
    reanchor_tol_mps: float
    max_wait_hazard: float
    q_rate: float
    switch_margin: float
    energy_scale_n2: float
    risk: RiskParams
    s2_unavailable: str
    reanchor_tol: str
    def __init__(self, threat_margin_m: _Optional[float] = ..., check_steps: _Optional[int] = ..., reanchor_tol_m: _Optional[float] = ..., reanchor_tol_mps: _Optional[float] = ..., max_wait_hazard: _Optional[float] = ..., q_rate: _Optional[float] = ..., switch_margin: _Optional[float] = ..., energy_scale_n2: _Optional[float] = ..., risk: _Optional[_Union[RiskParams, _Mapping]] = ..., s2_unavailable: _Optional[str] = ..., reanchor_tol: _Optional[str] = ...) -> None: ...

class ForecastParams(_message.Message):
    __slots__ = ("members", "resolution_m", "horizon_s", "interval_s")
    MEMBERS_FIELD_NUMBER: _ClassVar[int]
    RESOLUTION_M_FIELD_NUMBER: _ClassVar[int]
    HORIZON_S_FIELD_NUMBER: _ClassVar[int]
    INTERVAL_S_FIELD_NUMBER: _ClassVar[int]
    members: int
    resolution_m: float
    horizon_s: float
    interval_s: float
    def __init__(self, members: _Optional[int] = ..., resolution_m: _Optional[float] = ..., horizon_s: _Optional[float] = ..., interval_s: _Optional[float] = ...) -> None: ...

class MissionConfig(_message.Message):
    __slots__ = ("mission_id", "uav_id", "seed", "controller", "risk", "timing", "profile", "settings", "system1_method", "system2_method", "concurrent", "goal", "area_size_m", "start", "forecast", "system2_time_limit_s", "supervisor")
    MISSION_ID_FIELD_NUMBER: _ClassVar[int]
    UAV_ID_FIELD_NUMBER: _ClassVar[int]
    SEED_FIELD_NUMBER: _ClassVar[int]
    CONTROLLER_FIELD_NUMBER: _ClassVar[int]
    RISK_FIELD_NUMBER: _ClassVar[int]
    TIMING_FIELD_NUMBER: _ClassVar[int]
    PROFILE_FIELD_NUMBER: _ClassVar[int]
    SETTINGS_FIELD_NUMBER: _ClassVar[int]
    SYSTEM1_METHOD_FIELD_NUMBER: _ClassVar[int]
    SYSTEM2_METHOD_FIELD_NUMBER: _ClassVar[int]
    CONCURRENT_FIELD_NUMBER: _ClassVar[int]
    GOAL_FIELD_NUMBER: _ClassVar[int]
    AREA_SIZE_M_FIELD_NUMBER: _ClassVar[int]
    START_FIELD_NUMBER: _ClassVar[int]
    FORECAST_FIELD_NUMBER: _ClassVar[int]
    SYSTEM2_TIME_LIMIT_S_FIELD_NUMBER: _ClassVar[int]
    SUPERVISOR_FIELD_NUMBER: _ClassVar[int]
    mission_id: str
    uav_id: str
    seed: int
    controller: ControllerKind
    risk: bool
    timing: Timing
    profile: str
    settings: _containers.RepeatedCompositeFieldContainer[Setting]
    system1_method: str
    system2_method: str
    concurrent: ConcurrentParams
    goal: _common_pb2.Rect
    area_size_m: float
    start: _common_pb2.Vec2
    forecast: ForecastParams
    system2_time_limit_s: float
    supervisor: str
    def __init__(self, mission_id: _Optional[str] = ..., uav_id: _Optional[str] = ..., seed: _Optional[int] = ..., controller: _Optional[_Union[ControllerKind, str]] = ..., risk: _Optional[bool] = ..., timing: _Optional[_Union[Timing, str]] = ..., profile: _Optional[str] = ..., settings: _Optional[_Iterable[_Union[Setting, _Mapping]]] = ..., system1_method: _Optional[str] = ..., system2_method: _Optional[str] = ..., concurrent: _Optional[_Union[ConcurrentParams, _Mapping]] = ..., goal: _Optional[_Union[_common_pb2.Rect, _Mapping]] = ..., area_size_m: _Optional[float] = ..., start: _Optional[_Union[_common_pb2.Vec2, _Mapping]] = ..., forecast: _Optional[_Union[ForecastParams, _Mapping]] = ..., system2_time_limit_s: _Optional[float] = ..., supervisor: _Optional[str] = ...) -> None: ...
