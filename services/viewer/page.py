"""The operations picture as a Bokeh document: one per browser session of the web page.

The map (east/north, metres): each vehicle's area, goal and start, the
occupancy forecast as a heat map (P of fire at one horizon), the fire regions
and their hulls, the risk zones, each vehicle's trail, its current plan (the
flown system's colour), its d_safe disc and a marker pointing along its
velocity, coloured by the system that flies it. Beside it: a table of the
fleet (step, who flies, Ψ_t, A_t, d_t, the plans' status, the last event; an
HTML table, ``table.fleet``), the supervisor's Ψ_t over the steps of one
vehicle, and the newest events. Live, a periodic callback redraws what changed
(:meth:`Page.refresh`) unless the session is frozen; a replay adds a step
slider and a play button.

Every data source, renderer and widget has a ``name`` (``vehicles``, ``fires``,
``freeze``, …) so a test can read what the page holds
(``Bokeh.documents[0].get_model_by_name``).
"""

from __future__ import annotations

import html
import time
from collections.abc import Callable
from typing import Any

from bokeh.layouts import column, row
from bokeh.models import ColumnDataSource, HoverTool, LinearColorMapper, LogColorMapper
from bokeh.models.annotations import ColorBar, LabelSet
from bokeh.models.glyphs import Image
from bokeh.models.widgets import Button, Div, Select, Slider, Toggle
from bokeh.palettes import Viridis256
from bokeh.plotting import figure

from . import columns as C
from .picture import Frame

#: how often a session redraws (ms)
REFRESH_MS = 250
#: how fast a replay plays (ms a step)
PLAY_MS = 200
FIRE_FILL, FIRE_LINE, HULL_LINE = "#ff4019", "#d62410", "#ff9900"
RISK_LINE, TRAIL_LINE, SAFETY_LINE = "#b34dff", "#333333", "#d4a000"
SOURCES = ("area", "goal", "start", "fires", "hulls", "risk", "forecast", "trails",
           "altitude_trails", "plans", "safety", "vehicles", "psi")
#: the altitude colour scale's range (m) before a 3-D trail sets it: the default band
ALTITUDE_RANGE_M = (20.0, 120.0)


def _sources() -> dict[str, ColumnDataSource]:
    """The page's data sources, empty (the columns of a frame with no vehicle)."""
    blank = Frame()
    data = {**C.area_columns(blank), **C.fire_columns(blank), **C.vehicle_columns(blank),
            "forecast": C.forecast_columns(blank), "psi": C.psi_columns(blank, "")}
    return {name: ColumnDataSource(data=data[name], name=name) for name in SOURCES}


def map_figure(src: dict[str, ColumnDataSource], mapper: LogColorMapper,
               altitude: LinearColorMapper) -> Any:
    """The map: areas, forecast, fires, hulls, risk zones, trails (a 3-D one coloured by
    altitude, with its colour bar), plans, vehicles."""
    fig = figure(title="operations picture (east/north, m)", match_aspect=True,
                 sizing_mode="stretch_both", min_width=500, min_height=500,
                 tools="pan,wheel_zoom,box_zoom,reset,save", active_scroll="wheel_zoom",
                 x_axis_label="east (m)", y_axis_label="north (m)", name="map")
    fig.add_glyph(src["forecast"], Image(image="image", x="x", y="y", dw="dw", dh="dh",
                                         color_mapper=mapper), name="forecast_image")
    fig.multi_line("xs", "ys", source=src["area"], line_color="#9a9a9a", line_width=2)
    fig.patches("xs", "ys", source=src["goal"], fill_color="#1fcc4d", fill_alpha=0.35,
                line_color="#1a9e3f", name="goal_patches")
    fig.scatter("x", "y", source=src["start"], marker="circle_x", size=10, fill_color="white",
                line_color="#555555")
    fires = fig.patches("xs", "ys", source=src["fires"], fill_color=FIRE_FILL, fill_alpha=0.55,
                        line_color=FIRE_LINE, line_width=1.5, name="fire_patches")
    fig.multi_line("xs", "ys", source=src["hulls"], line_color=HULL_LINE, line_width=1.5)
    fig.multi_line("xs", "ys", source=src["risk"], line_color=RISK_LINE, line_width=1.5,
                   line_dash="dashed")
    fig.multi_line("xs", "ys", source=src["trails"], line_color=TRAIL_LINE, line_width=2,
                   name="trail_lines")
    fig.multi_line("xs", "ys", source=src["altitude_trails"], line_width=4,
                   line_color={"field": "altitude", "transform": altitude},
                   name="altitude_trail_lines")
    fig.multi_line("xs", "ys", source=src["plans"], line_color="color", line_width=3,
                   line_dash="dashed", name="plan_lines")
    fig.multi_line("xs", "ys", source=src["safety"], line_color=SAFETY_LINE, line_alpha=0.8)
    uavs = fig.scatter("x", "y", source=src["vehicles"], marker="triangle", size=20,
                       angle="angle", fill_color="color", line_color="black", line_width=1.5,
                       name="vehicle_markers")
    fig.add_layout(LabelSet(x="x", y="y", text="label", source=src["vehicles"], x_offset=12,
                            y_offset=6, text_font_size="11pt", text_font_style="bold"))
    fig.add_tools(HoverTool(renderers=[uavs], tooltips=[
        ("uav", "@uav"), ("step", "@step"), ("flies", "@flies"),
        ("east, north", "@x{0.0}, @y{0.0} m"),
        ("speed", "@speed{0.0} m/s"), ("altitude", "@altitude{0.0} m"),
        ("Ψ", "@psi1{0.000}, @psi2{0.000}")]))
    fig.add_tools(HoverTool(renderers=[fires], tooltips=[
        ("uav", "@uav"), ("front", "@front_id"), ("born at step", "@born_step")]))
    fig.add_layout(ColorBar(color_mapper=mapper, title="P(fire) at the horizon", width=12),
                   "right")
    fig.add_layout(ColorBar(color_mapper=altitude, title="altitude (m)", width=12,
                            visible=False, name="altitude_bar"), "right")
    return fig


def psi_figure(src: ColumnDataSource) -> Any:
    """Ψ_t of the selected vehicle over its steps; below, which system flew each step."""
    fig = figure(title="supervisor Ψ_t (Eq. Ψ)", height=240, sizing_mode="stretch_width",
                 x_axis_label="step t", tools="pan,wheel_zoom,reset", name="psi_plot")
    fig.line("t", "psi1", source=src, line_color=C.SYSTEM_COLORS[1], line_width=2,
             legend_label="Ψ₁ (System 1)")
    fig.line("t", "psi2", source=src, line_color=C.SYSTEM_COLORS[2], line_width=2,
             legend_label="Ψ₂ (System 2)")
    fig.scatter("t", "flown_y", source=src, marker="square", size=7, color="color",
                legend_label="flown (blue S1, magenta S2, red braked)")
    legend = fig.legend[0]
    legend.orientation = "horizontal"
    legend.label_text_font_size = "8pt"
    fig.add_layout(legend, "above")
    return fig


#: the fleet table's columns: (title, columns.table_columns key, format)
FLEET_COLUMNS = (("UAV", "uav", "{}"), ("step", "step", "{}"), ("flies", "flies", "{}"),
                 ("Ψ₁", "psi1", "{:.3f}"), ("Ψ₂", "psi2", "{:.3f}"), ("A_t", "attention", "{}"),
                 ("d_t (m)", "d_t_m", "{:.1f}"), ("plans", "plans", "{}"),
                 ("last event", "event", "{}"))


def _cell(fmt: str, value: Any) -> str:
    if isinstance(value, float) and value != value:  # NaN: not known yet
        return "-"
    return html.escape(fmt.format(value))


FLEET_CSS = ("<style>table.fleet{font:12px sans-serif;border-collapse:collapse;width:100%}"
             "table.fleet th,table.fleet td{padding:2px 6px;text-align:left;"
             "border-bottom:1px solid #ddd}</style>")


def fleet_html(frame: Frame) -> str:
    """The fleet table: one row a vehicle (who flies it, Ψ_t, A_t, d_t, the plans' status, its
    last event), the "flies" cell in the flown system's colour."""
    rows = C.table_columns(frame)
    head = "".join(f"<th>{html.escape(t)}</th>" for t, _, _ in FLEET_COLUMNS)
    body = []
    for i, flies in enumerate(rows["flies"]):
        cells = []
        for _, key, fmt in FLEET_COLUMNS:
            style = (f' style="color:{C.flown_color(C.FLOWN_NUMBER.get(flies))};'
                     f'font-weight:bold"' if key == "flies" else "")
            cells.append(f'<td class="{key}"{style}>{_cell(fmt, rows[key][i])}</td>')
        body.append(f"<tr>{''.join(cells)}</tr>")
    return f'{FLEET_CSS}<table class="fleet"><tr>{head}</tr>{"".join(body)}</table>'


def events_html(frame: Frame) -> str:
    colors = {"info": "#333", "warning": "#b36b00", "error": "#c0392b"}
    lines = "".join(f'<div style="color:{colors.get(level, "#333")}"><b>{html.escape(uav)}</b> '
                    f"{html.escape(text)}</div>" for uav, level, text in C.event_lines(frame))
    return f'<div style="font:12px monospace">{lines or "no events yet"}</div>'


def _on_change(model: Any, attr: str, action: Callable[[], None]) -> None:
    def callback(attr: str, old: Any, new: Any) -> None:
        action()

    model.on_change(attr, callback)


class Page:
    """One session's document: its sources and widgets, redrawn from the newest frame
    (``frames``), or in a replay of ``replay_steps`` steps from the one its slider shows
    (``step_frames``)."""

    def __init__(self, doc: Any, title: str, frames: Callable[[], Frame] | None = None,
                 step_frames: Callable[[int], Frame] | None = None, replay_steps: int = 0):
        self.doc, self.title = doc, title
        self.frames, self.step_frames = frames, step_frames
        self.src = _sources()
        self.drawn: dict[str, object] = {}
        self.mapper = LogColorMapper(palette=C.heat_palette(), low=C.HEAT_LOW_P, high=1.0,
                                     nan_color="#00000000", low_color="#00000000")
        self.altitude = LinearColorMapper(palette=Viridis256, low=ALTITUDE_RANGE_M[0],
                                          high=ALTITUDE_RANGE_M[1], name="altitude_mapper")
        self.header = Div(text="", sizing_mode="stretch_width", name="header")
        self.events = Div(text="", sizing_mode="stretch_width", name="events")
        self.fleet = Div(text="", sizing_mode="stretch_width", name="fleet")
        self.uav = Select(title="Ψ of", value="", options=[], width=120, name="psi_vehicle")
        furthest: list[str | tuple[Any, str]] = [("-1", "furthest")]
        self.horizon = Select(title="forecast horizon", value="-1", options=furthest,
                              width=140, name="horizon")
        _on_change(self.uav, "value", self.redraw)
        _on_change(self.horizon, "value", self.redraw)
        self.slider: Slider | None = None
        #: live: this session's picture held still (to look at a moment), the stack going on
        self.freeze = Toggle(label="❚❚ freeze", active=False, width=100, name="freeze")
        _on_change(self.freeze, "active", self.toggle_freeze)
        controls: list[Any] = [self.uav, self.horizon]
        if not replay_steps:
            controls.append(self.freeze)
        if replay_steps:
            self.slider = Slider(start=0, end=max(replay_steps - 1, 1), value=replay_steps - 1,
                                 step=1, title="step", width=400, name="replay_step")
            _on_change(self.slider, "value", self.refresh)
            self.play = Button(label="▶ play", width=90, name="play")
            self.play.on_click(self.toggle_play)
            self.playing: Any = None
            controls = [self.slider, self.play, *controls]
        side = column(self.fleet, psi_figure(self.src["psi"]), self.events,
                      sizing_mode="stretch_width", width=560)
        doc.add_root(column(self.header, row(*controls),
                            row(map_figure(self.src, self.mapper, self.altitude), side,
                                sizing_mode="stretch_both"),
                            sizing_mode="stretch_both"))
        doc.title = title
        self.refresh()
        doc.add_periodic_callback(self.refresh, REFRESH_MS)

    def toggle_freeze(self) -> None:
        self.freeze.label = "▶ follow live" if self.freeze.active else "❚❚ freeze"
        self.refresh()

    # -- replay -----------------------------------------------------------------------------------
    def toggle_play(self) -> None:
        assert self.slider is not None
        if self.playing is None:
            if self.slider.value >= self.slider.end:
                self.slider.value = 0
            self.playing = self.doc.add_periodic_callback(self.advance, PLAY_MS)
            self.play.label = "❚❚ pause"
        else:
            self.doc.remove_periodic_callback(self.playing)
            self.playing = None
            self.play.label = "▶ play"

    def advance(self) -> None:
        assert self.slider is not None
        if self.slider.value >= self.slider.end:
            self.toggle_play()
        else:
            self.slider.value += 1

    # -- drawing ----------------------------------------------------------------------------------
    def redraw(self) -> None:
        """Draw everything again (a widget changed what is shown)."""
        self.drawn.clear()
        self.refresh()

    def _assign(self, name: str, key: object, make: Callable[[], dict[str, Any]]) -> None:
        if self.drawn.get(name) != key:
            for src_name, data in make().items():
                self.src[src_name].data = data
            self.drawn[name] = key

    def frame(self) -> Frame:
        if self.slider is not None and self.step_frames is not None:
            return self.step_frames(int(self.slider.value))
        assert self.frames is not None
        return self.frames()

    def refresh(self) -> None:
        """Redraw the layers that changed since this session last drew them (none while the
        live picture is frozen)."""
        if self.freeze.active and self.slider is None:
            return
        f = self.frame()
        k = int(self.horizon.value)
        self._assign("area", f.layer_key("area"), lambda: C.area_columns(f))
        self._assign("fires", (f.layer_key("fires"), f.layer_key("risk")),
                     lambda: C.fire_columns(f))
        self._assign("forecast", (f.layer_key("forecast"), k),
                     lambda: {"forecast": C.forecast_columns(f, k)})
        self._assign("vehicles", tuple(f.layer_key(x) for x in ("vehicle", "path", "plans",
                                                                   "decision")),
                     lambda: C.vehicle_columns(f))
        self._altitude_scale()
        fleet_key = tuple(f.layer_key(x) for x in ("vehicle", "decision", "plans", "event"))
        if self.drawn.get("fleet") != fleet_key:
            self.fleet.text = fleet_html(f)
            self.drawn["fleet"] = fleet_key
        self._widgets(f)
        self._assign("psi", (f.layer_key("decision"), self.uav.value),
                     lambda: {"psi": C.psi_columns(f, self.uav.value)})
        if self.drawn.get("events_html") != f.layer_key("event"):
            self.events.text = events_html(f)
            self.drawn["events_html"] = f.layer_key("event")
        self.header.text = self.header_html(f)

    def _altitude_scale(self) -> None:
        """The altitude colours span the 3-D trails' altitudes (1 m at least); their colour bar
        shows only while there is one."""
        z = self.src["altitude_trails"].data["altitude"]
        bar = self.doc.select_one({"name": "altitude_bar"})
        if bar is not None and bar.visible != bool(z):
            bar.visible = bool(z)
        if z:
            low, high = float(min(z)), float(max(z))
            self.altitude.update(low=low, high=max(high, low + 1.0))

    def _widgets(self, f: Frame) -> None:
        """The vehicle and horizon choices follow the vehicles and forecasts seen."""
        names: list[str | tuple[Any, str]] = [v.uav for v in f.vehicles]
        if names != self.uav.options:
            self.uav.options = names
        if names and self.uav.value not in names:
            self.uav.value = f.vehicles[0].uav
        horizons = next((v.forecast.horizons_s for v in f.vehicles if v.forecast), ())
        opts: list[str | tuple[Any, str]] = [("-1", "furthest")]
        opts += [(str(i), f"+{h:g} s") for i, h in enumerate(horizons)]
        if opts != self.horizon.options:
            self.horizon.options = opts

    def header_html(self, f: Frame) -> str:
        newest = max((v.updated_ns for v in f.vehicles), default=0)
        if self.slider is not None:
            when = f"replay: step {self.slider.value} of {self.slider.end}"
        elif newest:
            when = f"live: newest message {max(0.0, time.time() - newest / 1e9):.1f} s ago"
        else:
            when = "live: waiting for the stack's first message"
        rows = C.table_columns(f)
        flying = ", ".join(f"{u} {s}" for u, s in zip(rows["uav"], rows["flies"], strict=True))
        return (f"<b>{html.escape(self.title)}</b> &nbsp; {len(f.vehicles)} vehicle(s) "
                f"&nbsp; {html.escape(when)} &nbsp; <span id='flying'>{html.escape(flying)}"
                f"</span>")
