"""Every bench under bench/ still runs as its module docstring says, and prints the JSON it promises.

Reviewers re-run the benches for the figures they quote (rule 4), and nothing else ran them: a probe that no
longer fits its stage (bench/core_stages.py until e9135be) or a heap that no longer holds the core
(bench/dshot.py, bench/rx_parse.py, bench/bundle_loop.py) showed only when someone needed the figure.
Each case runs a bench as a subprocess as its docstring's command does (CPython, or the MicroPython VM with
the MICROPYPATH and heap the docstring gives) with its smallest option, and checks that it exits cleanly and
that the last line of its stdout is JSON with the keys the docstring names. The figures are not judged here:
they come from full runs, and the docs hold them with their commands.

Left out, for their time:
- the valgrind benches (core_instructions, stage_instructions, pass_peaks, call_cost, output_instructions,
  rc_instructions, log_instructions, estimator --count, imu_decode --instructions, bundle_loop's counts):
  a minute or more each. Their `--child` runs, which fly the flight and make the counted calls, run here
  without valgrind at a tiny N, for every stage, call or variant the bench counts; frame_sizes --per-pass
  and bridge_firmware --instructions have no child of their own (the plain runs are here);
- bench/core_loop.py: tests/test_perf_rules.py runs it on the VM from source, and the bundle_loop case
  below from the flash bundle; its --rpm, --plane and --rx-core1 flights are left to a hand run;
- bundle_heap (6 s: builds the 32-bit bundle and searches its heap), and fuzz's server campaigns and soak's
  minutes (a parsers-only fuzz and a one-second soak run here).

The file takes about 50 s on the 2-core host: `.venv/bin/python -m pytest tests/test_bench_scripts.py -q
-p no:cacheprovider`.
"""

import ast
import json
import os
import re
import subprocess
import sys

import pytest

from test_micropython import MICROPYTHON, ROOT

BENCH = ROOT / "bench"
TIMEOUT_S = 180


def _run(argv, micropypath=None, timeout=TIMEOUT_S):
    env = dict(os.environ)
    if micropypath is not None:
        env["MICROPYPATH"] = micropypath
    return subprocess.run(argv, capture_output=True, text=True, timeout=timeout, cwd=str(ROOT), env=env)


def _python(script, *args, **kw):
    return _run([sys.executable, str(BENCH / script)] + list(args), **kw)


def _vm(script, heap, micropypath, *args, exe=None):
    if MICROPYTHON is None and exe is None:
        pytest.skip("the MicroPython VM is not installed")
    argv = [exe or MICROPYTHON] + (["-X", "heapsize=" + heap] if heap else []) + [str(BENCH / script)]
    return _run(argv + list(args), micropypath=micropypath)


def _ok(out):
    assert out.returncode == 0, "exit %d\n%s" % (out.returncode, (out.stderr or out.stdout)[-2000:])
    return out


def _last_json(out):
    lines = _ok(out).stdout.strip().splitlines()
    assert lines, "no output"
    try:
        return json.loads(lines[-1])
    except ValueError:
        raise AssertionError("the last line is not JSON: %r" % lines[-1][:300]) from None


def _missing(obj, keys):
    """The dotted key paths (`vm.loop_us`) that obj lacks."""
    gone = []
    for path in keys:
        node = obj
        for part in path.split("."):
            if not isinstance(node, dict) or part not in node:
                gone.append(path)
                break
            node = node[part]
    return gone


def _check(out, keys):
    result = _last_json(out)
    assert isinstance(result, dict), result
    assert not _missing(result, keys), "missing %s in %s" % (_missing(result, keys), sorted(result))
    return result


def _documented_vm(script):
    """(MICROPYPATH, heap) of the first MicroPython VM command in the bench's docstring (either may be None)."""
    doc = ast.get_docstring(ast.parse((BENCH / script).read_text()))
    m = re.search(r"(?:MICROPYPATH=(\S+)\s+)?\S*micropython\s+(?:-X heapsize=(\S+)\s+)?bench/%s\b"
                  % re.escape(script), doc)
    assert m, "%s's docstring gives no MicroPython command" % script
    return m.group(1), m.group(2)


def _vm_as_documented(script, *args):
    micropypath, heap = _documented_vm(script)
    return _vm(script, heap, micropypath, *args)


def _constant(script, name):
    """A module-level constant of a bench (the names its main loop counts), read without importing it."""
    for node in ast.parse((BENCH / script).read_text()).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == name for t in node.targets):
            return ast.literal_eval(node.value)
    raise AssertionError("%s has no %s" % (script, name))


# --- on both runtimes, as their docstrings run them (the VM's MICROPYPATH and heap read from there) -------

ATTR_STORE = ("runtime", "stores", "us_per_store.plain", "us_per_store.with_property", "us_per_store.subclass")
CORE_STAGES = ("runtime", "passes", "step_us", "step_bytes", "probe_us", "probe_bytes", "stages", "nested",
               "step_self_us")
DSHOT = ("implementation", "encode_motors_4_float_us", "encode_values_4_int_us", "dshot_frame_x4_us",
         "output_encoder_write_4_us", "erpm_decode_code_us", "encode_motors_4_float_alloc_bytes")
ESTIMATOR = tuple("%s.%s" % (k, v) for k in ("us_per_call", "bytes_per_call")
                  for v in ("float", "fixed", "fixed_floats", "fixed_sum")) + ("runtime", "calls")
IMU_DECODE = tuple("%s.%s" % (m, k) for m in ("axis_map", "aligned")
                   for k in ("read_us", "bus_us", "driver_us", "alloc_bytes_per_read"))
LINKS_TASK = ("runtime", "idle_us_per_run", "companion_us_per_run", "idle_bytes_per_run", "companion_bytes_per_run")
LOG_LOOP = ("runtime", "us_per_pass_off", "us_per_pass_on", "log_us_per_pass", "log_pct", "log_pct_of_best",
            "log_us_best_diff", "log_us_mean", "task_us", "bytes_per_s")
NOTCH = ("runtime", "calls") + tuple("%s_%s.%s" % (stage, n, f) for stage, counts in (
    ("rpm_float", ("h1", "h3")), ("rpm_fixed", ("h1", "h3")), ("dyn_float", ("1", "3")), ("dyn_fixed", ("1", "3")))
    for n in counts for f in ("us", "bytes"))
PARAM_CHECK = ("runtime", "valid_us_per_call", "hostile_us_per_call", "unknown_name_us_per_call")
RC_INPUT = tuple("%s_%s" % (k, u) for k in ("rc_update_fixed", "rc_update_float", "new_frame_fixed",
                                             "new_frame_float", "rx_update_idle", "rx_update_frame")
                 for u in ("us", "bytes")) + ("fs_switch_in_us",)
RX_PARSE = ("runtime", "crsf_us_per_frame", "sbus_us_per_frame", "ibus_us_per_frame", "crsf_split_us_per_frame",
            "receiver_stage_us_per_frame", "bytes_per_frame", "sbus_bytes_per_frame", "ibus_bytes_per_frame",
            "receiver_stage_bytes_per_frame")
SERVO_MIX = tuple("%s.%s" % (k, v) for k in ("airplane", "flying_wing", "rules8_speed")
                  for v in ("rules", "us_per_pass", "bytes_per_pass"))
ULOG = ("implementation", "write_data_us_null_sink", "alloc_bytes_per_sample", "px4_set_1khz_us_per_loop")
YAW_HOLD = ("runtime", "update_off_us", "update_off_bytes", "update_on_us", "update_on_bytes", "hold_heading_us",
            "hold_heading_bytes")

BOTH = [
    ("attr_store.py", (), ATTR_STORE),
    ("dshot.py", (), DSHOT),
    ("estimator.py", (), ESTIMATOR),
    ("imu_decode.py", ("--reads", "200"), IMU_DECODE),
    ("links_task.py", (), LINKS_TASK),
    ("log_loop.py", (), LOG_LOOP),
    ("notch_filters.py", ("--calls", "50"), NOTCH),
    ("param_check.py", (), PARAM_CHECK),
    ("rc_input.py", ("--passes", "200"), RC_INPUT),
    ("rx_parse.py", ("--frames", "200"), RX_PARSE),
    ("servo_mix.py", ("--passes", "200"), SERVO_MIX),
    ("ulog_write.py", (), ULOG),
    ("yaw_hold.py", ("--passes", "200"), YAW_HOLD),
]


def _runtime(result):
    for key in ("runtime", "implementation", "impl"):
        if key in result:
            return result[key]
    raise AssertionError("no runtime named in %s" % sorted(result))


@pytest.mark.parametrize("script,args,keys", BOTH, ids=[c[0] for c in BOTH])
def test_bench_runs_on_cpython_and_prints_its_json(script, args, keys):
    assert _runtime(_check(_python(script, *args), keys)) == "cpython"


@pytest.mark.parametrize("script,args,keys", BOTH, ids=[c[0] for c in BOTH])
def test_bench_runs_on_the_micropython_vm_as_its_docstring_says(script, args, keys):
    assert _runtime(_check(_vm_as_documented(script, *args), keys)) == "micropython"


def test_core_stages_probes_every_float_stage_on_cpython():
    result = _check(_python("core_stages.py", "--passes", "100"), CORE_STAGES)
    assert result["runtime"] == "cpython"
    for name in ("read_imu", "gyro_filter (math)", "accel_filter (math)", "mahony (math)", "rc.update",
                 "commander.update", "controller (math)", "mixer", "output.update", "write_motors"):
        assert name in result["stages"], (name, sorted(result["stages"]))
    assert "failsafe.observe" in result["nested"], sorted(result["nested"])


def test_core_stages_probes_every_fixed_point_stage_on_micropython():
    # The fixed-point stages are MicroPython's pass: a probe whose arity no longer fits one stops the bench
    # (until e9135be, FixedRate.update's).
    result = _check(_vm_as_documented("core_stages.py", "--passes", "100"), CORE_STAGES)
    assert result["runtime"] == "micropython"
    for name in ("read_imu", "fixed: gyro + accel filters", "fixed: estimator", "rc.update", "commander.update",
                 "fixed: controller + mixer", "fixed: motor commands", "write_motors", "scheduler.run (+tasks)"):
        assert name in result["stages"], (name, sorted(result["stages"]))
    assert "failsafe.observe" in result["nested"], sorted(result["nested"])


# --- MicroPython-only benches -----------------------------------------------------------------------------


def test_fixed_pass_times_the_fixed_stages_and_counts_them_with_count():
    _check(_vm_as_documented("fixed_pass.py"), ("runtime", "calls", "rate_us", "rate_bytes", "imu_us", "imu_bytes"))
    for only in ("rate", "imu"):
        assert _ok(_vm_as_documented("fixed_pass.py", "--count", "50", "--only", only)).stdout == ""


@pytest.mark.parametrize("heap", ["192k", "384k"])
def test_heap_look_times_a_look_at_the_free_heap(heap):
    result = _check(_vm("heap_look.py", heap, None), ("runtime", "heap_bytes", "mem_free_us", "mem_alloc_us"))
    assert result["heap_bytes"] > 0


def test_notch_filters_run_on_the_32_bit_vm():
    from test_micropython32 import MP32

    if not os.path.exists(MP32):
        pytest.skip("no 32-bit MicroPython at %s" % MP32)
    assert _check(_vm("notch_filters.py", "4m", "src", "--calls", "20", exe=MP32), NOTCH)["word_bits"] == 32


# --- CPython-only benches (some drive the VM or a `hoverfly sim` themselves) -------------------------------


def test_float_stages_times_every_float_stage():
    stages = ("controller", "pid_roll", "pid_yaw", "mixer", "control_float", "rc", "commander", "estimate",
              "gyro_filter", "accel_filter")
    _check(_python("float_stages.py", "--calls", "500"),
           ("native_modules",) + tuple("us_per_call." + s for s in stages))


def test_frame_sizes_lists_the_heap_frames_from_the_vms_bytecode_dump():
    result = _check(_python("frame_sizes.py"), ("limit_words", "heap_frames"))
    assert all(words > result["limit_words"] for _, _, words in result["heap_frames"])


def test_log_loop_same_flight_times_one_logged_flight():
    keys = ("runtime", "method", "us_per_pass_off", "log_us_per_pass", "log_pct")
    assert _check(_python("log_loop.py", "--same-flight"), keys)["method"] == "same-flight"


def test_sim_rtf_gives_the_real_time_factor_and_where_a_step_goes():
    keys = ("realtime_factor", "realtime_factor_cpu", "steps_per_s", "setup_s", "native_modules", "shares_pct",
            "us_per_step.flight core", "us_per_step.physics")
    _check(_python("sim_rtf.py", "--runs", "1", "--no-profile", "--duration", "1"), keys)


def test_sim_rtf_with_the_firmware_on_the_vm():
    if MICROPYTHON is None:
        pytest.skip("the MicroPython VM is not installed")
    keys = ("realtime_factor", "host_cpu_us_per_step", "firmware_cpu_us_per_step", "firmware_pass_mean_us",
            "load_avg_1min")
    result = _check(_python("sim_rtf.py", "--firmware", "micropython", "--duration", "0.5"), keys)
    assert result["firmware"] == "micropython"


def test_bridge_firmware_takes_a_bridged_step_apart():
    if MICROPYTHON is None:
        pytest.skip("the MicroPython VM is not installed")
    live = ("realtime_factor", "step_us", "wait_us", "write_us", "host_us", "sim_us")
    vm = ("loop_us", "start_ms", "pass_us", "slack_us", "gc_runs", "heap_looks", "exchange_us", "mem_free_us",
          "alloc_bytes.mean", "alloc_bytes.max")
    _check(_python("bridge_firmware.py", "--duration", "0.5"), ["live." + k for k in live] + ["vm." + k for k in vm])


def test_plane_model_measures_each_airframe_beside_its_expected_ranges():
    # the one bench that prints its JSON indented: a list, one object per airframe
    result = json.loads(_ok(_python("plane_model.py", "--airframe", "trainer")).stdout)
    keys = ("trim_speed_m_s", "best_glide_ratio", "stall_speed_m_s", "roll_rate_dps", "physics_step_us", "expected")
    assert [r["airframe"] for r in result] == ["trainer"]
    assert not _missing(result[0], keys), _missing(result[0], keys)


def test_msp_rate_takes_every_companion_frame_in_order():
    keys = ("rc_sent", "rc_taken", "rc_in_order", "rc_accepted", "polls_sent", "polls_answered",
            "latency_ms_p50", "latency_ms_p99", "latency_ms_max", "error_replies")
    _check(_python("msp_rate.py", "--seconds", "1"), keys)


def test_gcs_link_prints_a_line_per_port():
    out = _ok(_python("gcs_link.py", "--seconds", "0.2"))
    lines = [json.loads(line) for line in out.stdout.strip().splitlines()]
    keys = ("pump_ticks_per_s", "tick_link_ms_mean", "tick_link_ms_max", "stick_frames_per_s", "ws_telemetry_per_s")
    assert sorted(r["protocol"] for r in lines) == ["maint", "msp"]
    for r in lines:
        assert not _missing(r, keys), (r["protocol"], _missing(r, keys))


def test_fuzz_parsers_smoke_run():
    # Its JSON is indented (one object over many lines); servers are left out: a campaign takes seconds.
    result = json.loads(_ok(_python("fuzz.py", "--count", "200", "--servers", "none")).stdout)
    assert not _missing(result, ("parsers.crsf.inputs", "parsers.crsf.exceptions", "parsers.crsf.hangs",
                                 "parsers.crsf.worst_ms", "totals.inputs", "totals.exceptions", "totals.hangs"))
    assert result["totals"]["exceptions"] == 0


def test_soak_serves_a_sim_to_clients_that_poll_and_drop():
    result = json.loads(_ok(_python("soak.py", "--minutes", "0.02", "--sample-s", "0.5")).stdout)
    keys = ("minutes", "loop_hz.min", "loop_hz.mean", "rss_kb.first", "rss_kb.slope_kb_min", "requests", "answered",
            "unanswered", "reconnects", "exceptions", "deaths", "hangs")
    assert not _missing(result, keys), _missing(result, keys)


# --- the valgrind benches' children, run without valgrind at a tiny N -------------------------------------


def _child(script, heap, micropypath, *args):
    out = _ok(_vm(script, heap, micropypath, "--child", *args))
    assert "Traceback" not in out.stderr, out.stderr


def test_core_instructions_child_flies_the_counted_passes():
    _child("core_instructions.py", "640k", "src:bench", "5")


@pytest.mark.parametrize("stage", list(_constant("stage_instructions.py", "DEFAULT")) + ["core1:step"])
def test_stage_instructions_child_wraps_each_stage_it_counts(stage):
    _child("stage_instructions.py", "640k", "src:bench", stage, "5")


def test_pass_peaks_child_flies_a_place_of_the_cycle():
    _child("pass_peaks.py", "640k", "src:bench", "1", "1")


@pytest.mark.parametrize("kind", _constant("call_cost.py", "KINDS"))
def test_call_cost_child_makes_each_kind_of_call(kind):
    _child("call_cost.py", "8m", "src:bench", kind, "10")


@pytest.mark.parametrize("mode", ["write_motors", "motor_commands", "motor_test"])
def test_output_instructions_child_makes_each_output_call(mode):
    _child("output_instructions.py", "8m", "src:bench:.frozen", mode, "10")


@pytest.mark.parametrize("name", _constant("rc_instructions.py", "NAMES"))
@pytest.mark.parametrize("mode", ["pass", "idle"])
def test_rc_instructions_child_makes_each_receiver_call(name, mode):
    _child("rc_instructions.py", "8m", "src:bench", name, mode, "10")


@pytest.mark.parametrize("variant", ["loop", "float", "fixed", "fixed_floats", "fixed_sum"])
def test_estimator_count_child_runs_each_variant(variant):
    _child("estimator.py", "8m", "src:bench", variant, "10")


@pytest.mark.parametrize("mounting", ["axis_map", "aligned", "board"])
def test_imu_decode_instructions_child_reads_each_mounting(mounting):
    for mode in ("read", "bus"):
        _child("imu_decode.py", "8m", "src:bench:.frozen", mounting, mode, "10")


@pytest.mark.parametrize("log_on", ["off", "on"])
def test_log_instructions_child_flies_with_and_without_the_logger(log_on):
    out = _ok(_python("log_instructions.py", "--child", log_on, "10"))
    assert "Traceback" not in out.stderr, out.stderr


def test_bundle_loop_runs_core_loop_and_its_counted_child_from_the_flash_bundle(unix_bundle):
    # bench/bundle_loop.py times bench/core_loop.py on the bundle a board gets and counts
    # bench/core_instructions.py's child on it: both, from the bundle, in the heaps the bench gives them.
    if MICROPYTHON is None:
        pytest.skip("the MicroPython VM is not installed")
    code = ("import json, sys; sys.path.insert(0, %r); import bundle_loop; "
            "print(json.dumps(bundle_loop._time(%r, %r)))" % (str(BENCH), MICROPYTHON, str(unix_bundle / "lib")))
    assert _check(_run([sys.executable, "-c", code]), ("us_per_pass", "bytes_per_pass"))["runtime"] == "micropython"
    code = ("import subprocess, sys; sys.path.insert(0, %r); import bundle_loop as b; "
            "subprocess.run(b._child(%r) + ['--child', '5'], env=b._env(%r), check=True)"
            % (str(BENCH), MICROPYTHON, str(unix_bundle / "lib")))
    _ok(_run([sys.executable, "-c", code]))


def test_tree_compare_runs_core_loop_in_this_tree_and_an_exported_one():
    # HEAD against this checkout: the same code, so the same bytes a pass in both (the µs are the host's)
    if MICROPYTHON is None:
        pytest.skip("the MicroPython VM is not installed")
    if subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True).returncode:
        pytest.skip("not a git checkout: nothing to export")
    keys = ("rev", "runs", "heap", "trees.HEAD", "trees.this")
    result = _check(_python("tree_compare.py", "HEAD", "--runs", "1"), keys)
    trees = result["trees"]
    for tree in trees.values():
        assert not _missing(tree, ("us_per_pass", "us_per_pass_median", "tasks_us_per_pass", "loop_us_per_pass",
                                   "bytes_per_pass", "passes_per_gc")), sorted(tree)
    assert trees["HEAD"]["bytes_per_pass"] == trees["this"]["bytes_per_pass"]


def test_tree_compare_names_a_revision_git_cannot_export():
    out = _python("tree_compare.py", "no-such-revision")
    assert out.returncode == 1
    assert "git cannot export" in out.stderr
