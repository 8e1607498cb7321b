from services.msgs import common_pb2 as _common_pb2
from services.msgs import config_pb2 as _config_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class SliceEncoding(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    SLICE_ENCODING_RAW: _ClassVar[SliceEncoding]
    SLICE_ENCODING_ZLIB: _ClassVar[SliceEncoding]
SLICE_ENCODING_RAW: SliceEncoding
SLICE_ENCODING_ZLIB: SliceEncoding

class FireFront(_message.Message):
    __slots__ = ("front_id", "born_step", "speed_mps", "direction_rad", "region", "hull", "top_m", "hull_top_m")
    FRONT_ID_FIELD_NUMBER: _ClassVar[int]
    BORN_STEP_FIELD_NUMBER: _ClassVar[int]
    SPEED_MPS_FIELD_NUMBER: _ClassVar[int]
    DIRECTION_RAD_FIELD_NUMBER: _ClassVar[int]
    REGION_FIELD_NUMBER: _ClassVar[int]
    HULL_FIELD_NUMBER: _ClassVar[int]
    TOP_M_FIELD_NUMBER: _ClassVar[int]
    HULL_TOP_M_FIELD_NUMBER: _ClassVar[int]
    front_id: int
    born_step: int
    speed_mps: float
    direction_rad: float
    region: _common_pb2.Rect
    hull: _common_pb2.Polygon
    top_m: float
    hull_top_m: float
    def __init__(self, front_id: _Optional[int] = ..., born_step: _Optional[int] = ..., speed_mps: _Optional[float] = ..., direction_rad: _Optional[float] = ..., region: _Optional[_Union[_common_pb2.Rect, _Mapping]] = ..., hull: _Optional[_Union[_common_pb2.Polygon, _Mapping]] = ..., top_m: _Optional[float] = ..., hull_top_m: _Optional[float] = ...) -> None: ...

class FireState(_message.Message):
    __slots__ = ("header", "step", "substeps_done", "substep_s", "fronts", "extinct_hulls", "extinct_hull_tops_m")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    STEP_FIELD_NUMBER: _ClassVar[int]
    SUBSTEPS_DONE_FIELD_NUMBER: _ClassVar[int]
    SUBSTEP_S_FIELD_NUMBER: _ClassVar[int]
    FRONTS_FIELD_NUMBER: _ClassVar[int]
    EXTINCT_HULLS_FIELD_NUMBER: _ClassVar[int]
    EXTINCT_HULL_TOPS_M_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    step: int
    substeps_done: int
    substep_s: float
    fronts: _containers.RepeatedCompositeFieldContainer[FireFront]
    extinct_hulls: _containers.RepeatedCompositeFieldContainer[_common_pb2.Polygon]
    extinct_hull_tops_m: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., step: _Optional[int] = ..., substeps_done: _Optional[int] = ..., substep_s: _Optional[float] = ..., fronts: _Optional[_Iterable[_Union[FireFront, _Mapping]]] = ..., extinct_hulls: _Optional[_Iterable[_Union[_common_pb2.Polygon, _Mapping]]] = ..., extinct_hull_tops_m: _Optional[_Iterable[float]] = ...) -> None: ...

class FireForecast(_message.Message):
    __slots__ = ("header", "substeps_done", "substep_s", "horizon_s", "fronts", "occupancy", "step", "compute_s")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    SUBSTEPS_DONE_FIELD_NUMBER: _ClassVar[int]
    SUBSTEP_S_FIELD_NUMBER: _ClassVar[int]
    HORIZON_S_FIELD_NUMBER: _ClassVar[int]
    FRONTS_FIELD_NUMBER: _ClassVar[int]
    OCCUPANCY_FIELD_NUMBER: _ClassVar[int]
    STEP_FIELD_NUMBER: _ClassVar[int]
    COMPUTE_S_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    substeps_done: int
    substep_s: float
    horizon_s: float
    fronts: _containers.RepeatedCompositeFieldContainer[FrontForecast]
    occupancy: OccupancyGrid
    step: int
    compute_s: float
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., substeps_done: _Optional[int] = ..., substep_s: _Optional[float] = ..., horizon_s: _Optional[float] = ..., fronts: _Optional[_Iterable[_Union[FrontForecast, _Mapping]]] = ..., occupancy: _Optional[_Union[OccupancyGrid, _Mapping]] = ..., step: _Optional[int] = ..., compute_s: _Optional[float] = ...) -> None: ...

class OccupancyGrid(_message.Message):
    __slots__ = ("origin", "resolution_m", "rows", "cols", "horizons", "probabilities", "horizon_s", "substeps_per_step", "encoding")
    ORIGIN_FIELD_NUMBER: _ClassVar[int]
    RESOLUTION_M_FIELD_NUMBER: _ClassVar[int]
    ROWS_FIELD_NUMBER: _ClassVar[int]
    COLS_FIELD_NUMBER: _ClassVar[int]
    HORIZONS_FIELD_NUMBER: _ClassVar[int]
    PROBABILITIES_FIELD_NUMBER: _ClassVar[int]
    HORIZON_S_FIELD_NUMBER: _ClassVar[int]
    SUBSTEPS_PER_STEP_FIELD_NUMBER: _ClassVar[int]
    ENCODING_FIELD_NUMBER: _ClassVar[int]
    origin: _common_pb2.Vec2
    resolution_m: float
    rows: int
    cols: int
    horizons: _containers.RepeatedScalarFieldContainer[int]
    probabilities: _containers.RepeatedScalarFieldContainer[bytes]
    horizon_s: float
    substeps_per_step: int
    encoding: SliceEncoding
    def __init__(self, origin: _Optional[_Union[_common_pb2.Vec2, _Mapping]] = ..., resolution_m: _Optional[float] = ..., rows: _Optional[int] = ..., cols: _Optional[int] = ..., horizons: _Optional[_Iterable[int]] = ..., probabilities: _Optional[_Iterable[bytes]] = ..., horizon_s: _Optional[float] = ..., substeps_per_step: _Optional[int] = ..., encoding: _Optional[_Union[SliceEncoding, str]] = ...) -> None: ...

class FrontForecast(_message.Message):
    __slots__ = ("front_id", "regions", "envelope")
    FRONT_ID_FIELD_NUMBER: _ClassVar[int]
    REGIONS_FIELD_NUMBER: _ClassVar[int]
    ENVELOPE_FIELD_NUMBER: _ClassVar[int]
    front_id: int
    regions: _containers.RepeatedCompositeFieldContainer[_common_pb2.Rect]
    envelope: _common_pb2.Polygon
    def __init__(self, front_id: _Optional[int] = ..., regions: _Optional[_Iterable[_Union[_common_pb2.Rect, _Mapping]]] = ..., envelope: _Optional[_Union[_common_pb2.Polygon, _Mapping]] = ...) -> None: ...

class FireReset(_message.Message):
    __slots__ = ("seed", "area_size_m", "config")
    SEED_FIELD_NUMBER: _ClassVar[int]
    AREA_SIZE_M_FIELD_NUMBER: _ClassVar[int]
    CONFIG_FIELD_NUMBER: _ClassVar[int]
    seed: int
    area_size_m: float
    config: _config_pb2.MissionConfig
    def __init__(self, seed: _Optional[int] = ..., area_size_m: _Optional[float] = ..., config: _Optional[_Union[_config_pb2.MissionConfig, _Mapping]] = ...) -> None: ...

class FireAdvance(_message.Message):
    __slots__ = ("step", "substeps", "clock", "keep_out", "keep_out_m")
    STEP_FIELD_NUMBER: _ClassVar[int]
    SUBSTEPS_FIELD_NUMBER: _ClassVar[int]
    CLOCK_FIELD_NUMBER: _ClassVar[int]
    KEEP_OUT_FIELD_NUMBER: _ClassVar[int]
    KEEP_OUT_M_FIELD_NUMBER: _ClassVar[int]
    step: int
    substeps: int
    clock: _common_pb2.Clock
    keep_out: _common_pb2.Vec2
    keep_out_m: float
    def __init__(self, step: _Optional[int] = ..., substeps: _Optional[int] = ..., clock: _Optional[_Union[_common_pb2.Clock, _Mapping]] = ..., keep_out: _Optional[_Union[_common_pb2.Vec2, _Mapping]] = ..., keep_out_m: _Optional[float] = ...) -> None: ...

class FireForecastQuery(_message.Message):
    __slots__ = ("step", "substeps_done", "substeps_per_step", "digest")
    STEP_FIELD_NUMBER: _ClassVar[int]
    SUBSTEPS_DONE_FIELD_NUMBER: _ClassVar[int]
    SUBSTEPS_PER_STEP_FIELD_NUMBER: _ClassVar[int]
    DIGEST_FIELD_NUMBER: _ClassVar[int]
    step: int
    substeps_done: int
    substeps_per_step: int
    digest: bytes
    def __init__(self, step: _Optional[int] = ..., substeps_done: _Optional[int] = ..., substeps_per_step: _Optional[int] = ..., digest: _Optional[bytes] = ...) -> None: ...

class FireCommand(_message.Message):
    __slots__ = ("header", "mission_id", "reset", "advance", "forecast")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    MISSION_ID_FIELD_NUMBER: _ClassVar[int]
    RESET_FIELD_NUMBER: _ClassVar[int]
    ADVANCE_FIELD_NUMBER: _ClassVar[int]
    FORECAST_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    mission_id: str
    reset: FireReset
    advance: FireAdvance
    forecast: FireForecastQuery
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., mission_id: _Optional[str] = ..., reset: _Optional[_Union[FireReset, _Mapping]] = ..., advance: _Optional[_Union[FireAdvance, _Mapping]] = ..., forecast: _Optional[_Union[FireForecastQuery, _Mapping]] = ...) -> None: ...

class FireUpdate(_message.Message):
    __slots__ = ("header", "states", "paced_wait_s", "forecast")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    STATES_FIELD_NUMBER: _ClassVar[int]
    PACED_WAIT_S_FIELD_NUMBER: _ClassVar[int]
    FORECAST_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    states: _containers.RepeatedCompositeFieldContainer[FireState]
    paced_wait_s: float
    forecast: FireForecast
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., states: _Optional[_Iterable[_Union[FireState, _Mapping]]] = ..., paced_wait_s: _Optional[float] = ..., forecast: _Optional[_Union[FireForecast, _Mapping]] = ...) -> None: ...
