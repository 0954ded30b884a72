"""Fixtures every test module may ask for, and the suite's own instrument: CPU seconds per test.

``real_case(name)``: a real log imported and exported once per test run (tests/real_cases.py, on
tests/cache.py's one-build-per-run folders).

``--cpu-top N``: the N tests and modules that used the most CPU, load-independent, and the N tests that
waited the most (wall time less CPU).

Wall-clock durations (``--durations``) say how long a test waited on a busy machine; the CPU a test
burns, its own process's and its subprocesses' (the daemon, the simulator, the map process, Dask's
workers), says what it costs wherever it runs. Each phase (setup, call, teardown) is measured in the
process that runs it (an xdist worker) and travels to the controller in the report's
``user_properties``, so ``pytest -n 2 --cpu-top 40`` prints one table for the whole run. A module- or
session-scoped fixture's cost lands on the first test that asks for it.
"""

from __future__ import annotations

# `pytest -n 2` on two cores: one BLAS and OpenMP thread per worker, set before numpy is first imported.
# More only oversubscribe the cores (fjord_tide's diagnose: 53 s of CPU on two threads for 38 s of wall
# time, 37 s on one for 37 s); the `forcemap` command starts so too (the rule's one home is threads.py)
from forcemap.host.workbench.engine.threads import one_thread_by_default

one_thread_by_default()

import resource
import time
from collections import defaultdict

import pytest

from tests.real_cases import Cases, shared_root

CPU = "cpu_s"  # the user property: (own process, children) CPU seconds of one phase
_PHASE_CPU = pytest.StashKey[dict[str, tuple[float, float]]]()


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--cpu-top",
        type=int,
        default=0,
        metavar="N",
        help="print the N tests and test modules that used the most CPU (own + subprocesses)",
    )


def _cpu_now() -> tuple[float, float]:
    """This process's CPU seconds, and those of its children that have ended and been waited for."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time(), children.ru_utime + children.ru_stime


def _measured(item: pytest.Item, phase: str):
    own, kids = _cpu_now()
    yield
    own2, kids2 = _cpu_now()
    item.stash.setdefault(_PHASE_CPU, {})[phase] = (own2 - own, kids2 - kids)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item: pytest.Item):
    yield from _measured(item, "setup")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item: pytest.Item):
    yield from _measured(item, "call")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item: pytest.Item):
    yield from _measured(item, "teardown")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    outcome = yield
    spent = item.stash.get(_PHASE_CPU, {}).get(call.when)
    if spent is not None:
        outcome.get_result().user_properties.append((CPU, spent))


class _CpuTable:
    """Collects the phases' CPU on the controller and prints the largest at the end."""

    def __init__(self) -> None:
        self.by_test: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0])
        self.phases: dict[str, list[tuple[float, float, str]]] = defaultdict(list)  # by worker
        self.began = time.time()

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        worker = getattr(getattr(report, "node", None), "gateway", None)
        self.phases[worker.id if worker else "main"].append(
            (report.start, report.stop, report.nodeid)
        )
        for name, value in report.user_properties:
            if name == CPU:
                spent = self.by_test[report.nodeid]
                spent[0] += value[0]
                spent[1] += value[1]

    def pytest_terminal_summary(self, terminalreporter, config: pytest.Config) -> None:
        n = config.getoption("--cpu-top")
        if not self.by_test:
            return
        by_module: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0])
        for nodeid, (own, kids) in self.by_test.items():
            m = by_module[nodeid.split("::")[0]]
            m[0] += own
            m[1] += kids
        own_total = sum(v[0] for v in self.by_test.values())
        kids_total = sum(v[1] for v in self.by_test.values())
        tr = terminalreporter
        tr.write_sep("=", f"CPU seconds: {own_total + kids_total:.0f} (tests' own "
                          f"{own_total:.0f}, their subprocesses' {kids_total:.0f})")  # fmt: skip
        for title, table in (("tests", self.by_test), ("modules", by_module)):
            tr.write_line(f"the {n} {title} that used the most CPU: total = own + subprocesses")
            ranked = sorted(table.items(), key=lambda kv: -(kv[1][0] + kv[1][1]))[:n]
            for name, (own, kids) in ranked:
                tr.write_line(f"{own + kids:8.1f} s = {own:7.1f} + {kids:7.1f}  {name}")
        self._waits(tr, n)
        self._timeline(tr)

    def _waits(self, tr, n: int) -> None:  # type: ignore[no-untyped-def]
        """The tests whose wall time most exceeds their CPU: clocks, sockets, a shared build's lock.
        While one waits, its worker's core is idle."""
        wall: dict[str, float] = defaultdict(float)
        for phases in self.phases.values():
            for start, stop, nodeid in phases:
                wall[nodeid] += stop - start
        waits = {k: w - sum(self.by_test[k]) for k, w in wall.items() if k in self.by_test}
        tr.write_line(f"the {n} tests that waited the most (wall - CPU; {sum(waits.values()):.0f} s in all):")
        for name, waited in sorted(waits.items(), key=lambda kv: -kv[1])[:n]:
            tr.write_line(f"{waited:8.1f} s  {name}")

    def _timeline(self, tr) -> None:  # type: ignore[no-untyped-def]
        """Each worker's busy seconds, when it began and ended (s after the session began), and its
        last tests: how long one worker sat idle while the other finished."""
        end = time.time()
        tr.write_line(f"workers (session {end - self.began:.0f} s):")
        for worker, phases in sorted(self.phases.items()):
            busy = sum(b - a for a, b, _ in phases)
            first, last = min(a for a, _, _ in phases), max(b for _, b, _ in phases)
            tr.write_line(
                f"  {worker}: busy {busy:.0f} s, from {first - self.began:.0f} to "
                f"{last - self.began:.0f} s, idle {end - last:.0f} s at the end; last: "
                + ", ".join(list(dict.fromkeys(n.split("/")[-1] for _, _, n in sorted(phases)))[-3:])
            )


def pytest_configure(config: pytest.Config) -> None:
    if config.getoption("--cpu-top") > 0 and not hasattr(config, "workerinput"):
        config.pluginmanager.register(_CpuTable(), "forcemap-cpu-table")


@pytest.fixture(scope="session")
def real_case(tmp_path_factory) -> Cases:  # type: ignore[no-untyped-def]
    """``real_case(name)``: a real log imported and exported once per run (tests/real_cases.py)."""
    return Cases(shared_root(tmp_path_factory))
