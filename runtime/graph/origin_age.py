"""The worst origin age a graph's rates allow on every input that bounds it (``max_origin_age``).

An output's origin is the oldest origin of what its module read (``umbra.connectors.ports``), so the
age of the data behind a sample grows along a path by what each hop may add:

* a measured output (a sensor, the plant) starts anew: its sample is as old as the time since it
  was captured, at most one period of its module before the next one replaces it;
* a module that runs on its rate reads an input up to one period after it changed, and its own
  output then stands for up to one period: it adds its period;
* a module triggered by an input runs in the tick the input arrives and adds nothing (its output
  is replaced as soon as the input is);
* a link between processes adds its latency (``LINK_LATENCY_S``, loopback);
* an input fed from outside the graph (a ROS 2 topic: :class:`OutsideFeed`) starts with the worst
  age its declaration states (transport and clock error bound) and goes on like any other;
* event inputs (operator actions, paths) date a step only when they bring a new event, so they add
  nothing to a state's worst age.

What it does not count is time spent computing and waiting for a CPU: the figure is what the graph
allows when every step takes no time, so a graph whose figure is over a bound can never meet it,
and ``umbra check`` refuses it. A loop through which origins flow with no measured output on it
would never let them advance (every sample would keep the first origin forever): an error too.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from umbra.connectors.errors import Location
from umbra.runtime.graph.plan import ModulePlan
from umbra.runtime.graph.spec import ConnectionSpec

#: What a link between processes adds to an origin's age at the least, on loopback [s].
LINK_LATENCY_S = 0.002


@dataclass(frozen=True)
class Hop:
    """One step of a path and what it adds [s]."""

    what: str
    adds: float


@dataclass
class WorstAge:
    """The worst origin age [s] of a module's output and the path that makes it."""

    age: float
    path: list[Hop] = field(default_factory=list)

    def text(self) -> str:
        parts = [f"{h.what} +{h.adds * 1e3:.0f} ms" if h.adds else h.what for h in self.path]
        return " -> ".join(parts)


@dataclass(frozen=True)
class OutsideFeed:
    """Input ``module.port`` fed from outside the graph (a ROS 2 topic): ``worst``, the worst
    origin age [s] of what arrives there as its declaration states it; ``loc``, the declaration."""

    module: str
    port: str
    worst: WorstAge
    loc: Location

    @property
    def dst(self) -> str:
        return f"{self.module}.{self.port}"


@dataclass(frozen=True)
class BoundedInput:
    """An input with ``max_origin_age``, the bound and the worst age the graph allows there;
    ``connection`` feeds it (a connection of the graph, or a feed from outside)."""

    connection: ConnectionSpec | OutsideFeed
    bound: float
    worst: WorstAge


class OriginLoop(Exception):
    """Origins flow around a loop with no measured output: they would never advance."""

    def __init__(self, loop: list[str]) -> None:
        super().__init__(" -> ".join(loop))
        self.loop = loop


class _Ages:
    def __init__(
        self,
        modules: Mapping[str, ModulePlan],
        connections: Sequence[ConnectionSpec],
        outside: Sequence[OutsideFeed] = (),
    ) -> None:
        self.modules = modules
        self.outside = {(f.module, f.port): f for f in outside if f.module in modules}
        self.feeding: dict[tuple[str, str], list[ConnectionSpec]] = {}
        for conn in connections:
            if conn.src.module in modules and conn.dst.module in modules:
                self.feeding.setdefault((conn.dst.module, conn.dst.port), []).append(conn)
        self.memo: dict[tuple[str, str], WorstAge] = {}
        self.stack: list[tuple[str, str]] = []  # the outputs being followed

    def period(self, module: str) -> float:
        rate = self.modules[module].spec.rate
        return 1.0 / rate if rate else 0.0

    def events(self, conn: ConnectionSpec) -> bool:
        decl = self.modules[conn.src.module].cls.output_decls().get(conn.src.port)
        return bool(decl is not None and decl.events)

    def of_output(self, module: str, port: str) -> WorstAge:
        key = (module, port)
        if key in self.memo:
            return self.memo[key]
        if key in self.stack:
            loop = [m for m, _ in self.stack[self.stack.index(key) :]]
            raise OriginLoop([*loop, module])
        plan = self.modules[module]
        decl = plan.cls.output_decls()[port]
        period = self.period(module)
        name = f"{module}.{port}"
        if decl.origin_from == ():  # measured: a new origin, replaced every period
            worst = WorstAge(period, [Hop(f"{name} (measured)", period)])
        else:
            inputs = decl.origin_from if decl.origin_from is not None else list(plan.input_decls)
            self.stack.append(key)
            try:
                worst = self._through(module, inputs, name, period)
            finally:
                self.stack.pop()
        self.memo[key] = worst
        return worst

    def _through(self, module: str, inputs: Sequence[str], name: str, period: float) -> WorstAge:
        plan = self.modules[module]
        worst = WorstAge(0.0, [])
        for port in inputs:
            feeds = [
                self.arriving(c) for c in self.feeding.get((module, port), []) if not self.events(c)
            ]
            if (module, port) in self.outside:
                feeds.append(self.outside[(module, port)].worst)
            for arriving in feeds:
                if arriving.age > worst.age or not worst.path:
                    worst = arriving
        if not worst.path:  # reads nothing that dates it: its own stamp
            return WorstAge(period, [Hop(f"{name} (source)", period)])
        triggered = period == 0.0 or any(t in inputs for t in plan.triggers)
        adds = 0.0 if triggered else period
        return WorstAge(worst.age + adds, [*worst.path, Hop(name, adds)])

    def arriving(self, conn: ConnectionSpec) -> WorstAge:
        """The worst age of what ``conn`` delivers, as its consumer reads it."""
        upstream = self.of_output(conn.src.module, conn.src.port)
        if self.modules[conn.src.module].process == self.modules[conn.dst.module].process:
            return upstream
        hop = Hop(f"link {self.modules[conn.src.module].process}->", LINK_LATENCY_S)
        return WorstAge(upstream.age + LINK_LATENCY_S, [*upstream.path, hop])


def bounded_inputs(
    modules: Mapping[str, ModulePlan],
    connections: Sequence[ConnectionSpec],
    outside: Sequence[OutsideFeed] = (),
) -> list[BoundedInput]:
    """Every connection (or feed from ``outside``) into an input that declares
    ``max_origin_age``, with the worst origin age the graph allows there; raises
    :class:`OriginLoop`."""
    ages = _Ages(modules, connections, outside)
    out: list[BoundedInput] = []
    for feed in ages.outside.values():
        plan = modules[feed.module]
        decl = plan.input_decls.get(feed.port)
        bound = decl.resolve_max_origin_age(plan.params) if decl is not None else None
        if bound is not None:
            out.append(BoundedInput(feed, bound, feed.worst))
    for conn in connections:
        if conn.dst.module not in modules or conn.src.module not in modules:
            continue
        plan = modules[conn.dst.module]
        decl = plan.input_decls.get(conn.dst.port)
        bound = decl.resolve_max_origin_age(plan.params) if decl is not None else None
        if bound is None or ages.events(conn):
            continue
        out.append(BoundedInput(conn, bound, ages.arriving(conn)))
    return out


def check_origin_ages(
    modules: Mapping[str, ModulePlan],
    connections: Sequence[ConnectionSpec],
    error: Callable[[Location, str, str], None],
    outside: Sequence[OutsideFeed] = (),
) -> None:
    """Report every bounded input whose bound the graph's rates (and the declared ages of the
    feeds from ``outside``) cannot meet, and loops that would keep origins from advancing."""
    try:
        found = bounded_inputs(modules, connections, outside)
    except OriginLoop as loop:
        flow = loop.loop[::-1]  # followed upstream; said the way the data flows
        first = modules[flow[0]]
        error(
            first.spec.loc,
            f"origins flow around the loop {' -> '.join(flow)} with no measured output on "
            "it: every sample would keep the loop's first origin and look older and older",
            "declare the sensor's output `measured=True` (a camera, joint encoders, the plant)",
        )
        return
    for item in found:
        if item.worst.age > item.bound:
            error(
                item.connection.loc,
                f"`{item.connection.dst}` accepts commands made from sensor data up to "
                f"{item.bound:g} s old (max_origin_age), but the graph's rates allow "
                f"{item.worst.age:.3f} s: {item.worst.text()}",
                "raise the rates on that path, trigger its modules by their inputs, or raise "
                "max_origin_age",
            )
