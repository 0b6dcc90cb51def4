"""The Textual app of ``navgw monitor``: polls a frame source, feeds the state, shows panels.

The imperative shell around :class:`~gateway.monitor.bus_state.BusState` (the model) and
:mod:`~gateway.monitor.panels` (its text): a timer polls the source every :data:`TICK_S`,
feeds every frame to the state and redraws. Keys: ``n`` shows the next navigation source,
``q`` quits.
"""

from __future__ import annotations

from typing import ClassVar

from textual.app import App, ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Footer, Header, Label, Sparkline, Static

from gateway.monitor import panels
from gateway.monitor.bus_state import SPARKS, BusState
from gateway.monitor.sources import FrameSource

TICK_S = 0.1
MAX_FRAMES_PER_TICK = 20_000  # a fast log replay catches up over several ticks


def spark_id(key: str) -> str:
    """Widget id of the sparkline of ``key`` (``gyro x`` -> ``spark-gyro-x``)."""
    return "spark-" + key.replace(" ", "-")


class MonitorApp(App[None]):
    """navgw monitor: the state of a navgw (or any NMEA 2000 navigation source) at a glance."""

    TITLE = "navgw monitor"
    CSS = """
    #banner { background: $error; color: $text; text-style: bold; padding: 0 1; }
    #banner.hidden { display: none; }
    .panel { border: round $primary; padding: 0 1; height: auto; }
    #top { height: auto; }
    #status-panel, #motion { width: 1fr; }
    #bias-panel { width: 2fr; }
    #mode { text-style: bold; }
    #mode.good { color: $success; }
    #mode.bad { color: $error; }
    .spark-row { height: 1; }
    .spark-row Label { width: 18; }
    .spark-row Sparkline { width: 1fr; }
    #bottom { height: 1fr; }
    #rates { width: 1fr; }
    #claims { width: 2fr; }
    #sources, #counters { padding: 0 1; }
    """
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("q", "quit", "quit"),
        Binding("n", "next_source", "next source"),
    ]

    def __init__(self, source: FrameSource, state: BusState | None = None) -> None:
        super().__init__()
        self.source = source
        self.state = state or BusState()
        self.sub_title = source.description

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static(id="banner", classes="hidden")
        with Horizontal(id="top"):
            with Vertical(id="status-panel", classes="panel"):
                yield Static(id="mode")
                yield Static(id="status")
            yield Static(id="motion", classes="panel")
            with Vertical(id="bias-panel", classes="panel"):
                yield Static(id="biases")
                for key in SPARKS:
                    with Horizontal(classes="spark-row"):
                        yield Label(key, id=f"{spark_id(key)}-label")
                        yield Sparkline([], id=spark_id(key))
        with Horizontal(id="bottom"):
            yield DataTable(id="rates", cursor_type="none")
            yield DataTable(id="claims", cursor_type="none")
        yield Static(id="sources")
        yield Static(id="counters")
        yield Footer()

    def on_mount(self) -> None:
        self.query_one("#rates", DataTable).add_columns("output", "Hz", "configured", "")
        self.query_one("#claims", DataTable).add_columns("address", "who", "NAME")
        self.screen.set_interval(TICK_S, self.tick)  # stops with the screen's widgets
        self.show()

    def on_unmount(self) -> None:
        self.source.close()

    def tick(self) -> None:
        """Feed what arrived, then redraw."""
        for msg in self.source.poll(MAX_FRAMES_PER_TICK):
            self.state.feed(msg)
        self.show()

    def action_next_source(self) -> None:
        """Show the next navigation source on the bus."""
        self.state.select_next()
        self.show()

    def show(self) -> None:
        """Redraw every panel from the state."""
        now, state = self.source.now(), self.state
        src = state.current
        self._banner(now)
        mode = panels.mode_text(src)
        mode_widget = self.query_one("#mode", Static)
        mode_widget.update(f"mode      {mode}")
        mode_widget.set_class(mode == "NAVIGATING", "good")
        mode_widget.set_class(mode in ("FAULT", "DEGRADED"), "bad")
        self.query_one("#status", Static).update(panels.status_text(src))
        self.query_one("#motion", Static).update(panels.motion_text(src))
        self.query_one("#biases", Static).update(panels.bias_text(src))
        for key in SPARKS:
            values = list(src.sparks[key].values) if src is not None else []
            self.query_one(f"#{spark_id(key)}", Sparkline).data = values
            last = f" {values[-1]:+.4f}" if values else ""
            self.query_one(f"#{spark_id(key)}-label", Label).update(f"{key}{last}")
        rates = self.query_one("#rates", DataTable)
        rates.clear()
        rates.add_rows(panels.rate_rows(src, now))
        claims = self.query_one("#claims", DataTable)
        claims.clear()
        claims.add_rows(panels.claim_rows(state))
        self.query_one("#sources", Static).update(panels.sources_text(state))
        self.query_one("#counters", Static).update(panels.counters_text(state))

    def _banner(self, now: float) -> None:
        text = self.state.banner(now)
        if self.source.ended:
            text = f"END OF {self.source.description}: the state at its last frame"
        elif self.state.last_t is None:
            text = f"{text} from {self.source.description}: is the bus up, is navgw running?"
        banner = self.query_one("#banner", Static)
        banner.update(text)
        banner.set_class(not text, "hidden")
