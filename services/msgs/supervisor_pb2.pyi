from services.msgs import common_pb2 as _common_pb2
from services.msgs import plan_pb2 as _plan_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class MissionEventKind(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    MISSION_EVENT_KIND_UNSPECIFIED: _ClassVar[MissionEventKind]
    MISSION_EVENT_KIND_STARTED: _ClassVar[MissionEventKind]
    MISSION_EVENT_KIND_STEP: _ClassVar[MissionEventKind]
    MISSION_EVENT_KIND_ENDED: _ClassVar[MissionEventKind]
    MISSION_EVENT_KIND_ABORTED: _ClassVar[MissionEventKind]
    MISSION_EVENT_KIND_PAUSED: _ClassVar[MissionEventKind]
    MISSION_EVENT_KIND_RESUMED: _ClassVar[MissionEventKind]
    MISSION_EVENT_KIND_WAYPOINTS: _ClassVar[MissionEventKind]
MISSION_EVENT_KIND_UNSPECIFIED: MissionEventKind
MISSION_EVENT_KIND_STARTED: MissionEventKind
MISSION_EVENT_KIND_STEP: MissionEventKind
MISSION_EVENT_KIND_ENDED: MissionEventKind
MISSION_EVENT_KIND_ABORTED: MissionEventKind
MISSION_EVENT_KIND_PAUSED: MissionEventKind
MISSION_EVENT_KIND_RESUMED: MissionEventKind
MISSION_EVENT_KIND_WAYPOINTS: MissionEventKind

class Decision(_message.Message):
    __slots__ = ("header", "step", "d_t_m", "xi", "p", "attention", "psi", "system", "objective", "commanded_system", "plan_source", "operator_rejected", "operator_waypoints", "operator_note", "fire_stale", "fire_age_s", "fire_margin_m")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    STEP_FIELD_NUMBER: _ClassVar[int]
    D_T_M_FIELD_NUMBER: _ClassVar[int]
    XI_FIELD_NUMBER: _ClassVar[int]
    P_FIELD_NUMBER: _ClassVar[int]
    ATTENTION_FIELD_NUMBER: _ClassVar[int]
    PSI_FIELD_NUMBER: _ClassVar[int]
    SYSTEM_FIELD_NUMBER: _ClassVar[int]
    OBJECTIVE_FIELD_NUMBER: _ClassVar[int]
    COMMANDED_SYSTEM_FIELD_NUMBER: _ClassVar[int]
    PLAN_SOURCE_FIELD_NUMBER: _ClassVar[int]
    OPERATOR_REJECTED_FIELD_NUMBER: _ClassVar[int]
    OPERATOR_WAYPOINTS_FIELD_NUMBER: _ClassVar[int]
    OPERATOR_NOTE_FIELD_NUMBER: _ClassVar[int]
    FIRE_STALE_FIELD_NUMBER: _ClassVar[int]
    FIRE_AGE_S_FIELD_NUMBER: _ClassVar[int]
    FIRE_MARGIN_M_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    step: int
    d_t_m: float
    xi: _containers.RepeatedScalarFieldContainer[float]
    p: _containers.RepeatedScalarFieldContainer[float]
    attention: int
    psi: _containers.RepeatedScalarFieldContainer[float]
    system: int
    objective: _plan_pb2.Objective
    commanded_system: int
    plan_source: str
    operator_rejected: bool
    operator_waypoints: int
    operator_note: str
    fire_stale: bool
    fire_age_s: float
    fire_margin_m: float
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., step: _Optional[int] = ..., d_t_m: _Optional[float] = ..., xi: _Optional[_Iterable[float]] = ..., p: _Optional[_Iterable[float]] = ..., attention: _Optional[int] = ..., psi: _Optional[_Iterable[float]] = ..., system: _Optional[int] = ..., objective: _Optional[_Union[_plan_pb2.Objective, str]] = ..., commanded_system: _Optional[int] = ..., plan_source: _Optional[str] = ..., operator_rejected: _Optional[bool] = ..., operator_waypoints: _Optional[int] = ..., operator_note: _Optional[str] = ..., fire_stale: _Optional[bool] = ..., fire_age_s: _Optional[float] = ..., fire_margin_m: _Optional[float] = ...) -> None: ...

class MissionEvent(_message.Message):
    __slots__ = ("header", "kind", "mission_id", "controller", "seed", "step", "success", "failure_cause", "mission_time_s", "flown_system", "position", "fires_active", "plan_status", "message")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    KIND_FIELD_NUMBER: _ClassVar[int]
    MISSION_ID_FIELD_NUMBER: _ClassVar[int]
    CONTROLLER_FIELD_NUMBER: _ClassVar[int]
    SEED_FIELD_NUMBER: _ClassVar[int]
    STEP_FIELD_NUMBER: _ClassVar[int]
    SUCCESS_FIELD_NUMBER: _ClassVar[int]
    FAILURE_CAUSE_FIELD_NUMBER: _ClassVar[int]
    MISSION_TIME_S_FIELD_NUMBER: _ClassVar[int]
    FLOWN_SYSTEM_FIELD_NUMBER: _ClassVar[int]
    POSITION_FIELD_NUMBER: _ClassVar[int]
    FIRES_ACTIVE_FIELD_NUMBER: _ClassVar[int]
    PLAN_STATUS_FIELD_NUMBER: _ClassVar[int]
    MESSAGE_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    kind: MissionEventKind
    mission_id: str
    controller: str
    seed: int
    step: int
    success: bool
    failure_cause: str
    mission_time_s: float
    flown_system: int
    position: _common_pb2.Vec2
    fires_active: int
    plan_status: str
    message: str
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., kind: _Optional[_Union[MissionEventKind, str]] = ..., mission_id: _Optional[str] = ..., controller: _Optional[str] = ..., seed: _Optional[int] = ..., step: _Optional[int] = ..., success: _Optional[bool] = ..., failure_cause: _Optional[str] = ..., mission_time_s: _Optional[float] = ..., flown_system: _Optional[int] = ..., position: _Optional[_Union[_common_pb2.Vec2, _Mapping]] = ..., fires_active: _Optional[int] = ..., plan_status: _Optional[str] = ..., message: _Optional[str] = ...) -> None: ...

class StepPlans(_message.Message):
    __slots__ = ("header", "mission_id", "step", "step_time_s", "flown_system", "plans", "mission", "risk_zones", "risk_alpha")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    MISSION_ID_FIELD_NUMBER: _ClassVar[int]
    STEP_FIELD_NUMBER: _ClassVar[int]
    STEP_TIME_S_FIELD_NUMBER: _ClassVar[int]
    FLOWN_SYSTEM_FIELD_NUMBER: _ClassVar[int]
    PLANS_FIELD_NUMBER: _ClassVar[int]
    MISSION_FIELD_NUMBER: _ClassVar[int]
    RISK_ZONES_FIELD_NUMBER: _ClassVar[int]
    RISK_ALPHA_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    mission_id: str
    step: int
    step_time_s: float
    flown_system: int
    plans: _containers.RepeatedCompositeFieldContainer[SystemPlan]
    mission: _plan_pb2.MissionSpec
    risk_zones: _containers.RepeatedCompositeFieldContainer[_common_pb2.Polygon]
    risk_alpha: float
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., mission_id: _Optional[str] = ..., step: _Optional[int] = ..., step_time_s: _Optional[float] = ..., flown_system: _Optional[int] = ..., plans: _Optional[_Iterable[_Union[SystemPlan, _Mapping]]] = ..., mission: _Optional[_Union[_plan_pb2.MissionSpec, _Mapping]] = ..., risk_zones: _Optional[_Iterable[_Union[_common_pb2.Polygon, _Mapping]]] = ..., risk_alpha: _Optional[float] = ...) -> None: ...

class SystemPlan(_message.Message):
    __slots__ = ("system", "status", "positions_m")
    SYSTEM_FIELD_NUMBER: _ClassVar[int]
    STATUS_FIELD_NUMBER: _ClassVar[int]
    POSITIONS_M_FIELD_NUMBER: _ClassVar[int]
    system: int
    status: str
    positions_m: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, system: _Optional[int] = ..., status: _Optional[str] = ..., positions_m: _Optional[_Iterable[float]] = ...) -> None: ...
