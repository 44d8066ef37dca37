"""Scenario flights on the Pico's path: `pid_math = fixed` on CPython, judged as the float flights are.

On a Pico the pass runs the fixed-point stages (core/fastpass/fixedimu.py, fixedatt.py, fixedrate.py and the
fixed parts of rc.py and output.py, through their generated viper twins); on CPython the scenario
suite flies the float stages. Here a named subset of that suite, one that covers every flight mode
(acro, angle, horizon, altitude hold, the autopilot) and every failsafe (receiver loss, its stages
and restore, the failsafe switch's three procedures, a frozen or stuck IMU, the output failsafe,
arming refusals), is flown again with the fixed-point Python stages, by calling the scenario tests
themselves: the same flights, the same pilot's judgement, no copy of an assertion.

Every flight flown here is checked to have taken the fixed path: the fixed IMU filter, estimator and
rate loop (a plane's: its fixed-wing law, core/fastpass/fixedfw.py) ran and their float counterparts never
did. The planes (tests/test_plane_flight.py) bring MANUAL, the bank steps, the glide and the hand launch.
"""

import inspect

import pytest

import test_aux_modes as aux
import test_flight_scenarios as flights
import test_outputs_flight as outputs
import test_plane_flight as planes
import test_safety_scenarios as safety
from hoverfly.core.fastpass.fixedatt import FixedAttitude
from hoverfly.core.fastpass.fixedfw import FixedFw
from hoverfly.core.fastpass.fixedimu import FixedImuFilter
from hoverfly.core.fastpass.fixedrate import FixedRate
from hoverfly.core.stages.control import Controller
from hoverfly.core.stages.estimator import Mahony
from hoverfly.core.stages.filters import GyroFilter
from hoverfly.core.stages.fwcontrol import FwController
from hoverfly.sim import runner
from test_safety_scenarios import autopilot_run  # noqa: F401 - the autopilot flight, flown again here

# (the module, its test, the arguments it is given, the starting mode switch if not the scenario's)
SUBSET = (
    (flights, "test_hover_holds_level_within_a_degree", {"airframe": "5inch"}, None),  # angle, altitude hold
    (flights, "test_hover_holds_level_within_a_degree", {"airframe": "f450"}, None),
    (flights, "test_hover_holds_level_within_a_degree", {"airframe": "5inch"}, "horizon"),
    (flights, "test_acro_rate_step_to_400_rises_fast_without_much_overshoot", {"airframe": "5inch"}, None),
    (flights, "test_angle_step_to_30_degrees_is_quick_and_accurate", {"airframe": "5inch"}, None),
    (flights, "test_acro_flip_ends_level_and_loses_little_height", {"airframe": "5inch"}, None),
    (flights, "test_demo_flies_the_box_and_lands_disarmed", {"airframe": "5inch"}, None),
    (flights, "test_motors_stay_stopped_until_armed", {}, None),
    (safety, "test_rx_loss_mid_hover_lands_level_on_time_without_climb_or_drift", {"airframe": "5inch"}, None),
    (safety, "test_rx_loss_mid_hover_lands_level_on_time_without_climb_or_drift", {"airframe": "f450"}, None),
    (safety, "test_drop_disarms_at_stage_two", {}, None),
    (safety, "test_short_dropout_ends_in_stage_one_and_restored_link_does_not_take_over_a_landing", {}, None),
    (safety, "test_frozen_imu_in_flight_disarms_not_a_flyaway", {"airframe": "5inch"}, None),
    (safety, "test_imu_stuck_on_one_sample_is_an_imu_fault", {}, None),
    (safety, "test_arming_refusals_scenario_names_each_reason_then_arms", {}, None),
    (safety, "test_autopilot_msp_flood_and_arming_refused_before_the_procedure", {}, None),
    (safety, "test_autopilot_soft_override_roll_and_throttle_cap", {}, None),
    (safety, "test_autopilot_hard_override_latches_throttle_until_the_stick_comes_down", {}, None),
    (safety, "test_silent_autopilot_hands_back_to_the_pilot_and_arm_switch_off_disarms", {}, None),
    (aux, "test_failsafe_switch_stage1_runs_the_lost_receiver_timing_lands_and_disarms", {}, None),
    (aux, "test_failsafe_switch_stage2_goes_straight_to_the_procedure", {}, None),
    (aux, "test_failsafe_switch_kill_disarms_within_one_rx_frame", {}, None),
    (aux, "test_airmode_switch_turns_air_mode_on_and_off_in_flight", {}, None),
    (outputs, "test_output_failsafe_cuts_the_motors_100_ms_into_a_controller_stall", {}, None),
    # planes (issue 23): MANUAL, ANGLE's bank steps, the glide failsafe, the hand launch and box
    (planes, "test_manual_moves_the_surfaces_with_the_sticks_and_angle_levels_the_wings_again", {}, None),
    (planes, "test_a_30_degree_bank_step_reaches_90_percent_within_1_s_without_overshoot_or_steady_error",
     {"airframe": "wing", "seed": 1}, None),
    (planes, "test_rx_loss_at_cruise_glides_wings_level_with_the_motor_off_to_the_ground",
     {"airframe": "trainer", "seed": 1}, None),
    (planes, "test_a_hand_launched_plane_climbs_and_flies_the_box_in_angle_without_stalling",
     {"airframe": "trainer", "seed": 1}, None),
)

# The stages the fixed path runs instead of the float ones, and the float ones that must stay idle.
_FIXED = ((FixedImuFilter, "update"), (FixedAttitude, "step"), (FixedRate, "update"))
_FLOAT = ((GyroFilter, "update"), (Mahony, "update"), (Controller, "update"))
# a plane's: its controller in place of the quad's rate loop
_FIXED_PLANE = ((FixedImuFilter, "update"), (FixedAttitude, "step"), (FixedFw, "update"))
_FLOAT_PLANE = ((GyroFilter, "update"), (Mahony, "update"), (FwController, "update"))


def _ids():
    out = []
    for module, name, kwargs, mode in SUBSET:
        label = module.__name__.replace("test_", "", 1) + "." + name.replace("test_", "", 1)
        extra = [str(v) for v in kwargs.values()] + ([mode] if mode else [])
        out.append(label + ("[%s]" % ",".join(extra) if extra else ""))
    return out


class _Watch:
    """Counts the calls of the fixed and float stages during each flight, and the flights."""

    def __init__(self):
        self.calls = {}
        self.flights = 0
        self.mode = None  # the starting mode switch imposed on the next flights, or None


@pytest.fixture(scope="module", autouse=True)
def watch():
    """Every flight built in this module flies `pid_math = fixed`, and is checked to have done so."""
    w = _Watch()
    with pytest.MonkeyPatch.context() as mp:
        real_build = runner.build_params
        real_load = runner.load_scenario
        real_run = runner.SimRun.run

        def build_params(airframe, scenario, overrides):
            return real_build(airframe, scenario, tuple(overrides) + (("pid_math", "fixed"),))

        def load_scenario(name):
            scenario = real_load(name)
            if w.mode is not None:
                scenario = dict(scenario, mode=w.mode)
            return scenario

        def run(self):
            w.calls = {}
            result = real_run(self)
            w.flights += 1
            plane = self.plane_judge is not None
            fixed, flt = (_FIXED_PLANE, _FLOAT_PLANE) if plane else (_FIXED, _FLOAT)
            ran = {cls.__name__ + "." + meth: w.calls.get((cls, meth), 0) for cls, meth in fixed}
            floats = {cls.__name__ + "." + meth: w.calls.get((cls, meth), 0) for cls, meth in flt}
            assert all(ran.values()) and not any(floats.values()), (
                "this flight did not fly the fixed-point path the Pico flies (calls: fixed %r, float %r)"
                % (ran, floats))
            return result

        for cls, meth in set(_FIXED + _FLOAT + _FIXED_PLANE + _FLOAT_PLANE):
            mp.setattr(cls, meth, _counting(w, cls, meth, getattr(cls, meth)))
        mp.setattr(runner, "build_params", build_params)
        mp.setattr(runner, "load_scenario", load_scenario)
        mp.setattr(runner.SimRun, "run", run)
        yield w


def _counting(w, cls, meth, fn):
    key = (cls, meth)

    def counted(*args):
        w.calls[key] = w.calls.get(key, 0) + 1
        return fn(*args)

    return counted


@pytest.mark.parametrize("module, name, kwargs, mode", SUBSET, ids=_ids())
def test_the_scenario_flies_as_well_on_the_fixed_point_path(module, name, kwargs, mode, watch, request):
    test = getattr(module, name)
    args = dict(kwargs)
    for param in inspect.signature(test).parameters:
        if param not in args:
            args[param] = request.getfixturevalue(param)  # autopilot_run: flown here, on the fixed path
    before = watch.flights
    watch.mode = mode
    try:
        test(**args)
    finally:
        watch.mode = None
    assert watch.flights > before or "autopilot_run" in args, "the test flew no flight"


def test_the_subset_covers_every_flight_mode_and_failsafe():
    # A new mode or failsafe procedure must get a flight here: the names the flight core gives them.
    from hoverfly.core.config.params import FS_SWITCH_MODES
    from hoverfly.core.stages.control import MODE_NAMES

    text = " ".join(name for _, name, _, _ in SUBSET)
    modes = {mode or "" for _, _, _, mode in SUBSET}
    flown = set()
    for m in MODE_NAMES:
        if m in modes or m in text:
            flown.add(m)
    assert flown == set(MODE_NAMES), set(MODE_NAMES) - flown
    for procedure in FS_SWITCH_MODES:
        assert "failsafe_switch_" + procedure in text, procedure
    for failsafe in ("rx_loss", "dropout", "frozen_imu", "imu_stuck", "output_failsafe", "arming_refusals",
                     "autopilot"):
        assert failsafe in text, failsafe
