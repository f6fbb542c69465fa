"""Property-based tests (hypothesis) of the config parsers and the controller core (issue 14).

Config: every key of :class:`ScoopConfig` and of the robot node's config, with values of its own type
(in and out of range), of other types and garbage, gives either a valid config (which round-trips
through its dict) or a :class:`ConfigError` that names the key, never another exception. Each key
gets a few fixed corner values, then hypothesis draws 500 (key, value) pairs per config. The keys and each key's values
come from the models' fields, so a section added later is covered without touching this file.

Controller: random sequences of sensor messages (good, NaN, inf, out of range, missing joints),
stamps (fresh, late, frozen, 10 s old, far ahead, out of order, unstamped), silences, estops and
scoop starts and ends: every command is finite and within the limits, and from the moment an
input is stale or bad (by the watchdog's rules, modelled here from its specification) the speed is
zero within a millisecond (the loop's wake-up slack), well within the required
``input_timeout_s`` + one control period, until every input is healthy again.
"""

from __future__ import annotations

import bisect
import math
import types
import typing
from dataclasses import dataclass, field

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from autoscoop.core import kinematics
from autoscoop.core.config import ConfigError, ConfigModel, ScoopConfig
from autoscoop.deploy.controller import SENSOR_INPUTS, ControllerCore
from autoscoop.deploy.robot_config import RobotNodeConfig, robot_config_from_dict
from autoscoop.deploy.safety import CommandLimiter, Stamp

EXAMPLES = 500
PROPERTY = settings(max_examples=EXAMPLES, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
CONTROLLER_EXAMPLES = 200
"""Scenarios of the controller's loop (each hundreds of updates, a tenth of a second): fewer than the config's
quick examples, twice hypothesis's default."""


# ==================================================================== config: strategies from the fields
def field_of(model: type[ConfigModel], dotted: str):
    """The pydantic field behind a dotted key (sections by their YAML key, aliases included)."""
    *sections, leaf = dotted.split(".")
    for part in sections:
        model = next(f.annotation for name, f in model.model_fields.items() if (f.alias or name) == part)
    return next(f for name, f in model.model_fields.items() if (f.alias or name) == leaf)


def _model_in(annotation) -> type[ConfigModel] | None:
    options = typing.get_args(annotation) if typing.get_origin(annotation) in (typing.Union, types.UnionType) \
        else (annotation,)
    return next((a for a in options if isinstance(a, type) and issubclass(a, ConfigModel)), None)


def _bounds(metadata) -> tuple[float | None, float | None]:
    low = next((m.ge for m in metadata if hasattr(m, "ge")), None)
    high = next((m.le for m in metadata if hasattr(m, "le")), None)
    return low, high


GARBAGE = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(max_size=12),
                    st.lists(st.one_of(st.integers(), st.text(max_size=3)), max_size=3),
                    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2), st.just(10 ** 400))
"""Any value of the wrong kind (``st.floats()`` includes NaN and infinities)."""


def numbers_near(low: float | None, high: float | None, integer: bool = False) -> st.SearchStrategy:
    """Numbers in [low, high], just outside it, and anywhere."""
    if integer:
        near = st.integers(None if low is None else int(low) - 3, None if high is None else int(high) + 3)
        return st.one_of(st.integers(low, high), near, st.integers())
    span = 1.0 if low is None or high is None else max(high - low, 1e-6)
    inside = st.floats(low, high) if low is not None and high is not None else st.floats(allow_nan=False)
    near = st.floats(None if low is None else low - span, None if high is None else high + span, allow_nan=False)
    whole = st.integers(None if low is None else math.floor(low), None if high is None else math.ceil(high))
    return st.one_of(inside, near, whole, st.floats())


def values_for(annotation, extra: dict | None = None) -> st.SearchStrategy:
    """Values for a field of this type: of its type (in and out of range) and garbage."""
    extra = extra or {}
    low, high = extra.get("low"), extra.get("high")
    origin = typing.get_origin(annotation)
    model = _model_in(annotation)
    if annotation is bool:
        typed = st.one_of(st.booleans(), st.sampled_from(["true", "no", "1", 0, 1]))
    elif annotation is int:
        typed = numbers_near(low, high, integer=True)
    elif annotation is float:
        typed = numbers_near(low, high)
    elif annotation is str:
        typed = st.one_of(st.text(max_size=20), st.from_regex(r"\A~?/?[A-Za-z][A-Za-z0-9_/]{0,12}\Z"))
    elif origin is typing.Literal:
        typed = st.one_of(st.sampled_from(typing.get_args(annotation)), st.text(max_size=8))
    elif origin is tuple:
        item = typing.get_args(annotation)[0]
        item_low, item_high = _bounds(getattr(item, "__metadata__", ()) and item.__metadata__[0].metadata)
        items = numbers_near(item_low, item_high)
        typed = st.one_of(st.lists(items, max_size=4), st.lists(items, max_size=4).map(tuple),
                          st.lists(GARBAGE, max_size=3))
    elif model is not None:
        keys = {(f.alias or name): values_for(f.annotation, f.json_schema_extra)
                for name, f in model.model_fields.items()}
        typed = st.one_of(st.none(), st.fixed_dictionaries({}, optional=keys),
                          st.fixed_dictionaries(keys), st.dictionaries(st.text(max_size=4), GARBAGE, max_size=2))
    else:  # a kind of field this test does not know yet: garbage only
        typed = st.nothing()
    return st.one_of(typed, GARBAGE)


def _check_key(build, key: str, value, note=lambda outcome: None) -> None:
    """``build(key, value)`` gives a config that round-trips, or a ConfigError naming ``key``; ``note`` hears which."""
    try:
        config = build(key, value)
    except ConfigError as error:
        note("refused")
        assert key in str(error), f"{key} = {value!r}: the error does not name the key: {error}"
        return
    note("valid")
    assert type(config).from_dict(config.to_dict()) == config  # a valid one round-trips


def corner_values(f) -> list:
    """A few values every key gets, drawn or not: its default, its range's ends and just beyond, garbage."""
    extra = f.json_schema_extra or {}
    low, high = extra.get("low"), extra.get("high")
    ends = [x for x in (low, high) if x is not None]
    return [f.default, *ends, *[x - 1 for x in ends], *[x + 1 for x in ends], math.nan, math.inf, None, "x", "",
            [], [math.nan], {}, True, 10 ** 400]


def _property_over_keys(model: type[ConfigModel], build) -> None:
    keys = model.dotted_keys()
    for key in keys:  # every key, whatever hypothesis draws
        for value in corner_values(field_of(model, key)):
            _check_key(build, key, value)
    outcomes: list[str] = []

    @PROPERTY
    @given(st.data())
    def check(data):
        key = data.draw(st.sampled_from(keys), label="key")
        f = field_of(model, key)
        _check_key(build, key, data.draw(values_for(f.annotation, f.json_schema_extra), label="value"),
                   outcomes.append)

    check()
    assert len(outcomes) >= EXAMPLES and {"valid", "refused"} <= set(outcomes)  # neither vacuous nor all errors


def _scoop_override(key, value):
    return ScoopConfig().with_overrides({key: value})


def _robot_override(key, value):
    section, name = key.split(".", 1)
    return robot_config_from_dict({section: {name: value}})


def test_every_scoop_config_key_gives_a_config_or_an_error_naming_it():
    _property_over_keys(ScoopConfig, _scoop_override)


def test_every_robot_config_key_gives_a_config_or_an_error_naming_it():
    _property_over_keys(RobotNodeConfig, _robot_override)


def test_the_strategies_know_every_kind_of_field():
    """A field of a kind ``values_for`` does not know would get garbage only: say so, so it is taught."""
    for model in (ScoopConfig, RobotNodeConfig):
        for key in model.dotted_keys():
            f = field_of(model, key)
            assert not values_for(f.annotation, f.json_schema_extra).is_empty, key
            assert not (f.annotation not in (bool, int, float, str) and typing.get_origin(f.annotation)
                        not in (typing.Literal, tuple) and _model_in(f.annotation) is None), \
                f"{key}: teach values_for its type {f.annotation}"


# ==================================================================== the controller core
ROS_OFFSET_S = 1.7e9 + 0.37
"""The node's ROS clock minus its monotonic clock, s."""
SLACK_S = 1e-3
"""How long after an input turns stale or bad a zero speed may come (the loop wakes 0.1 ms late)."""
FLOAT_INPUTS = ("bucket_torque", "lift_torque")
STAMP_KINDS = ("fresh", "fresh", "fresh", "fresh", "fresh", "fresh", "frozen", "old", "ahead", "slightly_ahead",
               "out_of_order", "unstamped")


class RandomPolicy:
    """Actions anywhere, NaN and inf included; deterministic from its seed."""

    name = "random"

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def reset(self) -> None:
        pass

    def act(self, observation):
        a = self.rng.uniform(-3, 3, 3)
        if self.rng.random() < 0.05:
            a[self.rng.integers(3)] = self.rng.choice([np.nan, np.inf, -np.inf])
        return a


@dataclass
class Message:
    """One sensor message: its input, whether its values are good, its values, its stamp kind."""

    name: str
    good: bool
    values: tuple
    stamp_kind: str = "fresh"
    stamp_size: float = 0.0


@dataclass
class Step:
    """What happens at one instant: ``dt`` s after the previous one, messages or an estop / scoop."""

    dt: float
    messages: list[Message] = field(default_factory=list)
    estop: bool | None = None
    scoop: bool | None = None


BAD_NUMBERS = st.sampled_from([math.nan, math.inf, -math.inf, 1e6, -1e6, 1e308])


def _reading(name: str) -> st.SearchStrategy[Message]:
    lift, tilt = kinematics.LIFT_RANGE_RAD, kinematics.TILT_RANGE_RAD
    good = {"joint_states": st.tuples(st.floats(lift[0], lift[1]), st.floats(tilt[0], tilt[1])),
            "odom": st.tuples(st.floats(-0.5, 0.5)), "pile_range": st.tuples(st.floats(0.0, 3.9)),
            "bucket_torque": st.tuples(st.floats(-150, 150)), "lift_torque": st.tuples(st.floats(-150, 150))}[name]
    bad = {"joint_states": st.one_of(st.tuples(BAD_NUMBERS, st.floats(-0.4, 0.8)),
                                     st.tuples(st.floats(-0.05, 0.3), BAD_NUMBERS),
                                     st.tuples(st.sampled_from([0.5, -0.2]), st.just(0.0)), st.just(("missing",))),
           "odom": st.tuples(st.one_of(BAD_NUMBERS, st.sampled_from([2.0, -5.0]))),
           "pile_range": st.tuples(st.one_of(BAD_NUMBERS, st.sampled_from([-0.5, 4.5, 50.0]))),
           "bucket_torque": st.tuples(st.one_of(BAD_NUMBERS, st.sampled_from([250.0, -300.0]))),
           "lift_torque": st.tuples(st.one_of(BAD_NUMBERS, st.sampled_from([250.0, -300.0])))}[name]
    is_good = st.booleans().flatmap(lambda b: st.just(True) if b else st.booleans())  # 3/4 good
    values = is_good.flatmap(lambda ok: st.tuples(st.just(ok), good if ok else bad))
    if name in FLOAT_INPUTS:
        return values.map(lambda v: Message(name, v[0], v[1]))
    return st.tuples(values, st.sampled_from(STAMP_KINDS), st.floats(0.0, 1.0)).map(
        lambda v: Message(name, v[0][0], v[0][1], v[1], v[2]))


def _tick() -> st.SearchStrategy[list[Message]]:
    """Messages at one instant: usually every input, sometimes a few."""
    every = st.tuples(*[_reading(name) for name in SENSOR_INPUTS + FLOAT_INPUTS]).map(list)
    some = st.lists(st.sampled_from(SENSOR_INPUTS + FLOAT_INPUTS).flatmap(_reading), min_size=1, max_size=3)
    return st.one_of(every, every, every, some)


DT = st.one_of(st.just(0.02), st.floats(0.0, 0.05), st.floats(0.05, 0.4), st.floats(0.4, 1.5))
"""Time between steps, s: a sensor period, jitter, delays and silences longer than the timeout."""
STEP = st.one_of(
    st.builds(Step, DT, _tick()), st.builds(Step, DT, _tick()), st.builds(Step, DT, _tick()),
    st.builds(Step, DT, _tick()), st.builds(Step, DT, _tick()), st.builds(Step, DT, _tick()),
    st.builds(Step, DT, estop=st.booleans()), st.builds(Step, DT, scoop=st.booleans()))
SCENARIO = st.tuples(st.lists(STEP, min_size=1, max_size=40), st.sampled_from([0.2, 0.5, 1.0]),
                     st.sampled_from([0.0, 0.1, 0.5]), st.integers(0, 2 ** 16))


class Oracle:
    """Which inputs are stale or bad, by the watchdog's specification (not its code).

    Per input: the time its newest accepted reading was taken (stamped ones: the arrival time less
    the stamp's age, where the age is at least 0), its newest accepted stamp, and whether its last
    message was refused. A stamped message that repeats the newest accepted stamp changes nothing;
    another is refused when unstamped, ahead of the clock by more than the bound, older than the
    timeout, or older than the newest accepted stamp while that reading is fresh.
    """

    def __init__(self, timeout_s: float, max_future_s: float) -> None:
        self.timeout_s, self.max_future_s = timeout_s, max_future_s
        self.taken: dict[str, float] = {}
        self.stamp: dict[str, float] = {}
        self.bad: set[str] = set()
        self.estop = False

    def message(self, name: str, good: bool, now: float, stamp: Stamp | None) -> None:
        if not good:
            self.bad.add(name)
            return
        taken = now
        if stamp is not None:
            h, age = stamp.header_s, stamp.clock_s - stamp.header_s
            previous, fresh = self.stamp.get(name), name in self.taken and now - self.taken[name] <= self.timeout_s
            if h == previous:
                return
            if h <= 0 or age < -self.max_future_s or age > self.timeout_s or (
                    previous is not None and h < previous and fresh):
                self.bad.add(name)
                return
            self.stamp[name] = h
            taken = now - max(age, 0.0)
        self.taken[name] = max(taken, self.taken.get(name, -math.inf))
        self.bad.discard(name)

    def healthy(self, now: float) -> bool:
        """Every input present, good and fresh at ``now`` (a reading exactly the timeout old is still fresh: stale
        is older than the timeout), and no e-stop."""
        return not (self.estop or self.bad or set(self.taken) != set(SENSOR_INPUTS + FLOAT_INPUTS)) and all(
            now - taken <= self.timeout_s for taken in self.taken.values())

    def fault_from(self, now: float) -> float:
        """From when, at or after ``now`` and until the next message, an input is stale or bad (inf: none)."""
        if self.estop or self.bad or set(self.taken) != set(SENSOR_INPUTS + FLOAT_INPUTS):
            return now
        return max(now, min(t + self.timeout_s for t in self.taken.values()))


def _stamp(message: Message, now: float, sent: dict[str, float], timeout_s: float, max_future_s: float) -> Stamp:
    """The stamp of a message of this kind, sent at ``now``; ``sent`` holds each input's last stamp."""
    clock = now + ROS_OFFSET_S
    size, last = message.stamp_size, sent.get(message.name)
    header = {"fresh": clock - 0.9 * timeout_s * size, "frozen": clock if last is None else last,
              "old": clock - 1.01 * timeout_s - 100 * size, "ahead": clock + 1.01 * max_future_s + 0.001 + 1000 * size,
              "slightly_ahead": clock + 0.9 * max_future_s * size,
              "out_of_order": (clock if last is None else last) - 0.001 - 0.3 * size,
              "unstamped": 0.0}[message.stamp_kind]
    sent[message.name] = header
    return Stamp(header, clock)


def _send(core: ControllerCore, message: Message, now: float, stamp: Stamp | None) -> None:
    v = message.values
    if message.name == "joint_states":
        names, positions = (["lift"], [0.2]) if v == ("missing",) else (["tilt", "lift"], [v[1], v[0]])
        core.joint_states(names, positions, now, stamp)
    elif message.name == "odom":
        core.odometry(v[0], now, 0.0, stamp)
    elif message.name == "pile_range":
        core.pile_range(v[0], now, 0.0, 4.0, stamp)
    else:
        getattr(core, message.name)(v[0], now)


def simulate(steps: list[Step], timeout_s: float, max_future_s: float, seed: int):
    """Drive a core as the ROS node does; the commands published and the oracle's fault intervals."""
    config = robot_config_from_dict({"control": {"input_timeout_s": timeout_s, "max_future_stamp_s": max_future_s}})
    core = ControllerCore(config, RandomPolicy(seed), ScoopConfig())
    oracle = Oracle(timeout_s, max_future_s)
    sent: dict[str, float] = {}
    commands: list[tuple[float, object]] = []
    faults: list[list[float]] = []
    healthy_at = [-math.inf]  # the last instant every input was fresh and good, when a command was published
    t = 0.0
    for name in SENSOR_INPUTS + FLOAT_INPUTS:  # a healthy start: every input fresh, a scoop requested
        good = Message(name, True, (0.23, 0.0) if name == "joint_states" else (0.1,))
        stamp = None if name in FLOAT_INPUTS else _stamp(good, t, sent, timeout_s, max_future_s)
        _send(core, good, t, stamp)
        oracle.message(name, True, t, stamp)
    core.scoop(True, t)

    def publish(now):
        command = core.update(now)
        if command is not None:
            commands.append((now, command))

    def note_fault(start, end):
        if start >= end:
            return
        # two faults meet without merging where the inputs were healthy for an instant between them (a command
        # published then may drive, for no time at all)
        if faults and faults[-1][1] >= start and start != healthy_at[0]:
            faults[-1][1] = max(faults[-1][1], end)
        else:
            faults.append([start, end])

    def wake_ups(t, end):
        """The loop's wake-ups from ``t`` until ``end`` (exclusive)."""
        for _ in range(10_000):
            wake = core.next_wakeup(t)
            if wake >= end:
                return
            t = max(t, wake)
            publish(t)

    publish(t)
    for step in steps + [Step(2 * timeout_s)]:  # the last step: silence, every input goes stale
        end = t + step.dt
        note_fault(oracle.fault_from(t), end)
        wake_ups(t, end)
        t = end
        if step.estop is not None:
            core.estop(step.estop, t)
            oracle.estop = step.estop
        if step.scoop is not None:
            core.scoop(step.scoop, t)
        for message in step.messages:
            stamp = None if message.name in FLOAT_INPUTS else _stamp(message, t, sent, timeout_s, max_future_s)
            _send(core, message, t, stamp)
            oracle.message(message.name, message.good, t, stamp)
        if oracle.healthy(t):
            healthy_at[0] = t
        publish(t)
    return core, commands, faults


def _speed_at(commands, times, t) -> float:
    """The speed last published at or before ``t`` (0 before the first command)."""
    i = bisect.bisect_right(times, t)
    return 0.0 if i == 0 else commands[i - 1][1].speed_mps


@settings(PROPERTY, max_examples=CONTROLLER_EXAMPLES)
@given(SCENARIO)
def test_every_command_is_finite_within_limits_and_a_fault_stops_the_robot(scenario):
    steps, timeout_s, max_future_s, seed = scenario
    core, commands, faults = simulate(steps, timeout_s, max_future_s, seed)
    limiter = CommandLimiter(core.config.limits, core.period_s)
    for t, command in commands:
        assert limiter.contains(command), (t, command)
        assert math.isfinite(command.speed_mps)
    times = [t for t, _ in commands]
    moving = sum(c.speed_mps != 0.0 for _, c in commands)
    event("drove" if moving else "never drove")
    for start, end in faults:
        if end - start <= SLACK_S:
            continue
        assert _speed_at(commands, times, start + SLACK_S) == 0.0, (start, end, commands)
        moving = [(t, c) for t, c in commands if start + SLACK_S <= t < end and c.speed_mps != 0.0]
        assert not moving, (start, end, moving[:3])
    assert core.config.control.input_timeout_s + core.period_s > SLACK_S  # the requirement this is within


@pytest.mark.parametrize("kind", ["frozen", "old", "ahead", "out_of_order", "unstamped"])
def test_the_oracle_sees_each_stamp_fault(kind):
    """The model above is not vacuous: each stamp fault makes a fault interval, and the core stops."""
    healthy = [Step(0.02, [Message(n, True, (0.23, 0.0) if n == "joint_states" else (0.1,))
                           for n in SENSOR_INPUTS + FLOAT_INPUTS]) for _ in range(20)]
    fault = [Step(0.02, [Message(n, True, (0.23, 0.0) if n == "joint_states" else (0.1,),
                                 kind if n == "odom" else "fresh", 0.5 if n == "odom" else 0.0)
                         for n in SENSOR_INPUTS + FLOAT_INPUTS]) for _ in range(50)]
    core, commands, faults = simulate(healthy + fault, 0.5, 0.1, 0)
    assert faults and faults[0][0] == pytest.approx(0.40 + 0.5 if kind == "frozen" else 0.42)
    assert any(c.mode == "fault" and "odom" in c.reason for _, c in commands)
