from services.msgs import common_pb2 as _common_pb2
from services.msgs import config_pb2 as _config_pb2
from services.msgs import fire_pb2 as _fire_pb2
from services.msgs import vehicle_pb2 as _vehicle_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class Objective(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    OBJECTIVE_UNSPECIFIED: _ClassVar[Objective]
    OBJECTIVE_MISSION_TIME: _ClassVar[Objective]
    OBJECTIVE_ENERGY: _ClassVar[Objective]

class PlanStatus(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    PLAN_STATUS_UNSPECIFIED: _ClassVar[PlanStatus]
    PLAN_STATUS_OK: _ClassVar[PlanStatus]
    PLAN_STATUS_INFEASIBLE: _ClassVar[PlanStatus]
    PLAN_STATUS_TIMEOUT: _ClassVar[PlanStatus]
    PLAN_STATUS_NO_PATH: _ClassVar[PlanStatus]
    PLAN_STATUS_UNSAFE: _ClassVar[PlanStatus]
    PLAN_STATUS_INVALID_INPUT: _ClassVar[PlanStatus]
    PLAN_STATUS_ERROR: _ClassVar[PlanStatus]

class SpeedLimit(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    SPEED_LIMIT_UNSPECIFIED: _ClassVar[SpeedLimit]
    SPEED_LIMIT_AXIS: _ClassVar[SpeedLimit]
    SPEED_LIMIT_NORM: _ClassVar[SpeedLimit]
OBJECTIVE_UNSPECIFIED: Objective
OBJECTIVE_MISSION_TIME: Objective
OBJECTIVE_ENERGY: Objective
PLAN_STATUS_UNSPECIFIED: PlanStatus
PLAN_STATUS_OK: PlanStatus
PLAN_STATUS_INFEASIBLE: PlanStatus
PLAN_STATUS_TIMEOUT: PlanStatus
PLAN_STATUS_NO_PATH: PlanStatus
PLAN_STATUS_UNSAFE: PlanStatus
PLAN_STATUS_INVALID_INPUT: PlanStatus
PLAN_STATUS_ERROR: PlanStatus
SPEED_LIMIT_UNSPECIFIED: SpeedLimit
SPEED_LIMIT_AXIS: SpeedLimit
SPEED_LIMIT_NORM: SpeedLimit

class Dynamics(_message.Message):
    __slots__ = ("dt_s", "zeta", "mass_kg", "u_max_n", "v_max_mps", "speed_limit", "dim")
    DT_S_FIELD_NUMBER: _ClassVar[int]
    ZETA_FIELD_NUMBER: _ClassVar[int]
    MASS_KG_FIELD_NUMBER: _ClassVar[int]
    U_MAX_N_FIELD_NUMBER: _ClassVar[int]
    V_MAX_MPS_FIELD_NUMBER: _ClassVar[int]
    SPEED_LIMIT_FIELD_NUMBER: _ClassVar[int]
    DIM_FIELD_NUMBER: _ClassVar[int]
    dt_s: float
    zeta: float
    mass_kg: float
    u_max_n: float
    v_max_mps: float
    speed_limit: SpeedLimit
    dim: int
    def __init__(self, dt_s: _Optional[float] = ..., zeta: _Optional[float] = ..., mass_kg: _Optional[float] = ..., u_max_n: _Optional[float] = ..., v_max_mps: _Optional[float] = ..., speed_limit: _Optional[_Union[SpeedLimit, str]] = ..., dim: _Optional[int] = ...) -> None: ...

class MissionSpec(_message.Message):
    __slots__ = ("mission_id", "seed", "goal", "area_size_m", "start", "d_safe_m", "clearance_m", "dynamics")
    MISSION_ID_FIELD_NUMBER: _ClassVar[int]
    SEED_FIELD_NUMBER: _ClassVar[int]
    GOAL_FIELD_NUMBER: _ClassVar[int]
    AREA_SIZE_M_FIELD_NUMBER: _ClassVar[int]
    START_FIELD_NUMBER: _ClassVar[int]
    D_SAFE_M_FIELD_NUMBER: _ClassVar[int]
    CLEARANCE_M_FIELD_NUMBER: _ClassVar[int]
    DYNAMICS_FIELD_NUMBER: _ClassVar[int]
    mission_id: str
    seed: int
    goal: _common_pb2.Rect
    area_size_m: float
    start: _common_pb2.Vec2
    d_safe_m: float
    clearance_m: float
    dynamics: Dynamics
    def __init__(self, mission_id: _Optional[str] = ..., seed: _Optional[int] = ..., goal: _Optional[_Union[_common_pb2.Rect, _Mapping]] = ..., area_size_m: _Optional[float] = ..., start: _Optional[_Union[_common_pb2.Vec2, _Mapping]] = ..., d_safe_m: _Optional[float] = ..., clearance_m: _Optional[float] = ..., dynamics: _Optional[_Union[Dynamics, _Mapping]] = ...) -> None: ...

class PlanForecast(_message.Message):
    __slots__ = ("step", "substeps_done", "substep_s", "substeps_per_step", "offset_substeps", "occupancy", "digest")
    STEP_FIELD_NUMBER: _ClassVar[int]
    SUBSTEPS_DONE_FIELD_NUMBER: _ClassVar[int]
    SUBSTEP_S_FIELD_NUMBER: _ClassVar[int]
    SUBSTEPS_PER_STEP_FIELD_NUMBER: _ClassVar[int]
    OFFSET_SUBSTEPS_FIELD_NUMBER: _ClassVar[int]
    OCCUPANCY_FIELD_NUMBER: _ClassVar[int]
    DIGEST_FIELD_NUMBER: _ClassVar[int]
    step: int
    substeps_done: int
    substep_s: float
    substeps_per_step: int
    offset_substeps: int
    occupancy: _fire_pb2.OccupancyGrid
    digest: bytes
    def __init__(self, step: _Optional[int] = ..., substeps_done: _Optional[int] = ..., substep_s: _Optional[float] = ..., substeps_per_step: _Optional[int] = ..., offset_substeps: _Optional[int] = ..., occupancy: _Optional[_Union[_fire_pb2.OccupancyGrid, _Mapping]] = ..., digest: _Optional[bytes] = ...) -> None: ...

class PlanRequest(_message.Message):
    __slots__ = ("header", "mission", "step", "system", "objective", "state", "prev_control", "deadline_s", "prepare", "mission_id", "obstacles", "waypoints_revision", "config", "forecast", "obstacle_altitudes_m")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    MISSION_FIELD_NUMBER: _ClassVar[int]
    STEP_FIELD_NUMBER: _ClassVar[int]
    SYSTEM_FIELD_NUMBER: _ClassVar[int]
    OBJECTIVE_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    PREV_CONTROL_FIELD_NUMBER: _ClassVar[int]
    DEADLINE_S_FIELD_NUMBER: _ClassVar[int]
    PREPARE_FIELD_NUMBER: _ClassVar[int]
    MISSION_ID_FIELD_NUMBER: _ClassVar[int]
    OBSTACLES_FIELD_NUMBER: _ClassVar[int]
    WAYPOINTS_REVISION_FIELD_NUMBER: _ClassVar[int]
    CONFIG_FIELD_NUMBER: _ClassVar[int]
    FORECAST_FIELD_NUMBER: _ClassVar[int]
    OBSTACLE_ALTITUDES_M_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    mission: MissionSpec
    step: int
    system: int
    objective: Objective
    state: _vehicle_pb2.VehicleState
    prev_control: _common_pb2.Force2
    deadline_s: float
    prepare: bool
    mission_id: str
    obstacles: _containers.RepeatedCompositeFieldContainer[_common_pb2.Polygon]
    waypoints_revision: int
    config: _config_pb2.MissionConfig
    forecast: PlanForecast
    obstacle_altitudes_m: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., mission: _Optional[_Union[MissionSpec, _Mapping]] = ..., step: _Optional[int] = ..., system: _Optional[int] = ..., objective: _Optional[_Union[Objective, str]] = ..., state: _Optional[_Union[_vehicle_pb2.VehicleState, _Mapping]] = ..., prev_control: _Optional[_Union[_common_pb2.Force2, _Mapping]] = ..., deadline_s: _Optional[float] = ..., prepare: _Optional[bool] = ..., mission_id: _Optional[str] = ..., obstacles: _Optional[_Iterable[_Union[_common_pb2.Polygon, _Mapping]]] = ..., waypoints_revision: _Optional[int] = ..., config: _Optional[_Union[_config_pb2.MissionConfig, _Mapping]] = ..., forecast: _Optional[_Union[PlanForecast, _Mapping]] = ..., obstacle_altitudes_m: _Optional[_Iterable[float]] = ...) -> None: ...

class Plan(_message.Message):
    __slots__ = ("header", "step", "system", "status", "states", "controls", "compute_time_s", "objective", "cost", "path_m", "message", "info_json", "request_seq", "service_time_s", "bound", "certified_gap")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    STEP_FIELD_NUMBER: _ClassVar[int]
    SYSTEM_FIELD_NUMBER: _ClassVar[int]
    STATUS_FIELD_NUMBER: _ClassVar[int]
    STATES_FIELD_NUMBER: _ClassVar[int]
    CONTROLS_FIELD_NUMBER: _ClassVar[int]
    COMPUTE_TIME_S_FIELD_NUMBER: _ClassVar[int]
    OBJECTIVE_FIELD_NUMBER: _ClassVar[int]
    COST_FIELD_NUMBER: _ClassVar[int]
    PATH_M_FIELD_NUMBER: _ClassVar[int]
    MESSAGE_FIELD_NUMBER: _ClassVar[int]
    INFO_JSON_FIELD_NUMBER: _ClassVar[int]
    REQUEST_SEQ_FIELD_NUMBER: _ClassVar[int]
    SERVICE_TIME_S_FIELD_NUMBER: _ClassVar[int]
    BOUND_FIELD_NUMBER: _ClassVar[int]
    CERTIFIED_GAP_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    step: int
    system: int
    status: PlanStatus
    states: _containers.RepeatedScalarFieldContainer[float]
    controls: _containers.RepeatedScalarFieldContainer[float]
    compute_time_s: float
    objective: Objective
    cost: float
    path_m: _containers.RepeatedScalarFieldContainer[float]
    message: str
    info_json: str
    request_seq: int
    service_time_s: float
    bound: float
    certified_gap: float
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., step: _Optional[int] = ..., system: _Optional[int] = ..., status: _Optional[_Union[PlanStatus, str]] = ..., states: _Optional[_Iterable[float]] = ..., controls: _Optional[_Iterable[float]] = ..., compute_time_s: _Optional[float] = ..., objective: _Optional[_Union[Objective, str]] = ..., cost: _Optional[float] = ..., path_m: _Optional[_Iterable[float]] = ..., message: _Optional[str] = ..., info_json: _Optional[str] = ..., request_seq: _Optional[int] = ..., service_time_s: _Optional[float] = ..., bound: _Optional[float] = ..., certified_gap: _Optional[float] = ...) -> None: ...
