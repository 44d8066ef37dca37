"""The one parameter table, and the live set of values read by every stage's configure().

Each row: name (snake_case, <= 16 chars, Betaflight's where one fits), default, min, max,
unit, applies (LIVE or REBOOT), one-line help. A row whose default is a string is a
choice: its `unit` field is the tuple of allowed words. Storage, CLI, MSP, the maintenance
protocol, the ground station and the docs all read this table; no other file holds a
default, a range or a list of names.

Gains keep Betaflight's scales so a Betaflight tune is a sane start; stages convert them
to SI once, in configure().
"""

from hoverfly.core.stages.mixer import is_plane

LIVE = 0
REBOOT = 1

FRAMES = ("quadx", "quadx_seed000", "quadp", "hexx", "tri", "airplane", "flying_wing", "vtail")
MODES = ("acro", "angle", "horizon")
FILTER_TYPES = ("pt1", "pt2", "biquad")
TPA_MODES = ("pd", "d")
PID_MATHS = ("auto", "float", "fixed")
ESTIMATORS = ("mahony", "external")
FAILSAFE_PROCEDURES = ("drop", "land", "glide")
ARM_SOURCES = ("range", "seed001")
FS_SWITCH_MODES = ("stage1", "stage2", "kill")  # Betaflight failsafe_switch_mode

# fmt: off
#  name               default   min     max      unit           applies  help
PARAMS = (
    # --- loop, frame and motors
    ("loop_hz",           1000,  100,    8000,   "Hz",          REBOOT, "flight-loop (gyro + PID) rate"),
    ("mixer_type",      "quadx",   0,      0,    FRAMES,        REBOOT, "frame and motor order (quadx = Betaflight order)"),
    ("motor_idle_pct",     5.5,  0.0,    20.0,   "%",           LIVE,   "motor output when armed at zero throttle"),
    ("motor_max_pct",    100.0, 50.0,   100.0,   "%",           LIVE,   "highest motor output"),
    ("airmode",              1,    0,       1,   "",            LIVE,   "keep full PID authority at zero throttle"),
    ("yaw_motors_rev",       0,    0,       1,   "",            REBOOT, "props-in: reverse the yaw mix"),
    ("tri_servo_deg", 40.0,  5.0,    60.0,   "deg",         LIVE,   "tri: tail servo travel for full yaw"),
    # --- gyro and accelerometer
    ("gyro_lpf1_type",   "pt1",    0,      0,    FILTER_TYPES,  LIVE,   "gyro low-pass 1 type"),
    ("gyro_lpf1_hz",       250,    0,    1000,   "Hz",          LIVE,   "gyro low-pass 1 cutoff, 0 = off"),
    ("gyro_lpf2_hz",       500,    0,    4000,   "Hz",          LIVE,   "gyro low-pass 2 (PT1) cutoff; off at or above half the loop rate"),
    ("gyro_notch1_hz",       0,    0,    1000,   "Hz",          LIVE,   "gyro notch centre, 0 = off"),
    ("gyro_notch1_cut",      0,    0,    1000,   "Hz",          LIVE,   "gyro notch lower cutoff (sets its width)"),
    ("rpm_harmonics",        0,    0,       3,   "",            LIVE,   "RPM filter: notches per motor at its rotation frequency and harmonics (1..3), 0 = off; needs dshot_bidir"),
    ("rpm_min_hz",         100,   30,     200,   "Hz",          LIVE,   "RPM filter: lowest notch frequency (a notch below it is off)"),
    ("rpm_fade_hz",         50,    0,     200,   "Hz",          LIVE,   "RPM filter: a notch fades in over this range above rpm_min_hz"),
    ("rpm_filter_q",       500,  250,    3000,   "1/100",       LIVE,   "RPM filter: notch Q x 100 (500 = Q 5; higher is narrower)"),
    ("rpm_weight1_pct",    100,    0,     100,   "%",           LIVE,   "RPM filter: depth of the notch at the motor frequency"),
    ("rpm_weight2_pct",    100,    0,     100,   "%",           LIVE,   "RPM filter: depth of the 2nd-harmonic notch"),
    ("rpm_weight3_pct",    100,    0,     100,   "%",           LIVE,   "RPM filter: depth of the 3rd-harmonic notch"),
    ("dyn_notch_count",      0,    0,       3,   "",            LIVE,   "dynamic notches per gyro axis on the strongest spectrum peaks, 0 = off"),
    ("dyn_notch_q",        300,  100,    1000,   "1/100",       LIVE,   "dynamic notch Q x 100 (300 = Q 3)"),
    ("dyn_notch_min_hz",   100,   20,     250,   "Hz",          LIVE,   "dynamic notch: lowest peak tracked"),
    ("dyn_notch_max_hz",   600,  200,    1000,   "Hz",          LIVE,   "dynamic notch: highest peak tracked (at most 0.48 x loop_hz)"),
    ("acc_lpf_hz",          25,    0,     500,   "Hz",          LIVE,   "accelerometer low-pass (PT2) for the estimator, 0 = off"),
    ("gyro_cal_ms",       1000,  100,   10000,   "ms",          LIVE,   "boot gyro calibration: still time averaged"),
    ("gyro_cal_dps",       4.0,  0.5,    50.0,   "deg/s",       LIVE,   "boot gyro calibration: motion that restarts it"),
    ("acc_trim_roll",      0.0, -10.0,   10.0,   "deg",         LIVE,   "accelerometer trim, roll"),
    ("acc_trim_pitch",     0.0, -10.0,   10.0,   "deg",         LIVE,   "accelerometer trim, pitch"),
    ("board_roll_deg",     0.0, -180.0, 180.0,   "deg",         REBOOT, "board alignment: roll of the IMU in the frame"),
    ("board_pitch_deg",    0.0, -180.0, 180.0,   "deg",         REBOOT, "board alignment: pitch of the IMU in the frame"),
    ("board_yaw_deg",      0.0, -180.0, 180.0,   "deg",         REBOOT, "board alignment: yaw of the IMU in the frame"),
    # --- attitude estimator (Mahony)
    ("estimator",     "mahony",    0,      0,    ESTIMATORS,    REBOOT, "attitude source: mahony filter or the IMU's own fusion"),
    ("imu_dcm_kp",         300,    0,   50000,   "1e-4/s",      LIVE,   "accelerometer correction gain (x10 while disarmed)"),
    ("imu_dcm_ki",           0,    0,   50000,   "1e-4/s2",     LIVE,   "gyro-bias integral gain, Betaflight scale"),
    ("att_rate_hz",        250,   50,    8000,   "Hz",          LIVE,   "estimator rate, capped at loop_hz; the gyro is averaged between its updates"),
    ("small_angle",         25,    0,     180,   "deg",         LIVE,   "largest tilt that may arm"),
    # --- rate PID (Betaflight scales)
    ("p_roll",              45,    0,     250,   "",            LIVE,   "roll rate P"),
    ("i_roll",              80,    0,     250,   "",            LIVE,   "roll rate I"),
    ("d_roll",              40,    0,     250,   "",            LIVE,   "roll rate D (on measurement)"),
    ("f_roll",             120,    0,    1000,   "",            LIVE,   "roll feed-forward (setpoint change)"),
    ("p_pitch",             47,    0,     250,   "",            LIVE,   "pitch rate P"),
    ("i_pitch",             84,    0,     250,   "",            LIVE,   "pitch rate I"),
    ("d_pitch",             46,    0,     250,   "",            LIVE,   "pitch rate D (on measurement)"),
    ("f_pitch",            125,    0,    1000,   "",            LIVE,   "pitch feed-forward (setpoint change)"),
    ("p_yaw",               45,    0,     250,   "",            LIVE,   "yaw rate P"),
    ("i_yaw",               80,    0,     250,   "",            LIVE,   "yaw rate I"),
    ("d_yaw",                0,    0,     250,   "",            LIVE,   "yaw rate D (on measurement)"),
    ("f_yaw",              120,    0,    1000,   "",            LIVE,   "yaw feed-forward (setpoint change)"),
    ("ff_static_pct",      0.0,  0.0,   100.0,   "%",           LIVE,   "PIFF: rate setpoint fed straight to the output"),
    ("d_min_roll",           0,    0,     250,   "",            LIVE,   "roll D at rest, raised towards d_roll (D max) on fast moves; 0 = off"),
    ("d_min_pitch",          0,    0,     250,   "",            LIVE,   "pitch D at rest (D-min), 0 = off"),
    ("d_min_yaw",            0,    0,     250,   "",            LIVE,   "yaw D at rest (D-min), 0 = off"),
    ("d_min_gain",          37,    0,     100,   "",            LIVE,   "D-min: how strongly gyro movement raises D"),
    ("d_min_advance",       20,    0,     200,   "%",           LIVE,   "D-min: stick movement's share in raising D (before the gyro moves)"),
    ("ag_gain",              0,    0,     250,   "0.1x",        LIVE,   "anti-gravity: I (and P) boost on fast throttle moves, 80 = 8x; 0 = off"),
    ("ag_cutoff_hz",         5,    2,      50,   "Hz",          LIVE,   "anti-gravity: throttle-change smoothing cutoff"),
    ("ag_p_gain",          100,    0,     250,   "%",           LIVE,   "anti-gravity: share of the boost given to P"),
    ("pid_kt_roll",        0.0,  0.0,   1.0e6,   "",            LIVE,   "seed 001 roll KT (anti-windup tracking): kept and reported, unused"),
    ("pid_ad_roll",        0.0, -1.0e6, 1.0e6,   "",            LIVE,   "seed 001 roll AD (D-filter pole): kept and reported, unused"),
    ("pid_kt_pitch",       0.0,  0.0,   1.0e6,   "",            LIVE,   "seed 001 pitch KT: kept and reported, unused"),
    ("pid_ad_pitch",       0.0, -1.0e6, 1.0e6,   "",            LIVE,   "seed 001 pitch AD: kept and reported, unused"),
    ("pid_kt_yaw",         0.0,  0.0,   1.0e6,   "",            LIVE,   "seed 001 yaw KT: kept and reported, unused"),
    ("pid_ad_yaw",         0.0, -1.0e6, 1.0e6,   "",            LIVE,   "seed 001 yaw AD: kept and reported, unused"),
    ("dterm_lpf1_type",  "pt1",    0,      0,    FILTER_TYPES,  LIVE,   "D-term low-pass type"),
    ("dterm_lpf1_hz",       75,    0,     500,   "Hz",          LIVE,   "D-term low-pass cutoff, 0 = off"),
    ("iterm_relax",       "rp",    0,      0,    ("off", "rp", "rpy"), LIVE, "I-term relax on these axes while sticks move"),
    ("iterm_relax_hz",      15,    1,      50,   "Hz",          LIVE,   "I-term relax: setpoint low-pass cutoff"),
    ("iterm_limit",        400,    0,     500,   "",            LIVE,   "I-term limit, Betaflight PID-sum units"),
    ("pidsum_limit",       500,  100,    1000,   "",            LIVE,   "roll/pitch PID-sum limit, Betaflight units"),
    ("pidsum_limit_yaw",   400,  100,    1000,   "",            LIVE,   "yaw PID-sum limit, Betaflight units"),
    ("pid_math",        "auto",    0,      0,    PID_MATHS,     LIVE,   "PID and mixer arithmetic: auto = fixed point on MicroPython (no allocation), float elsewhere"),
    ("tpa_mode",           "d",    0,      0,    TPA_MODES,     LIVE,   "TPA reduces P and D, or D only"),
    ("tpa_rate",            65,    0,     100,   "%",           LIVE,   "TPA: gain cut at full throttle"),
    ("tpa_breakpoint",    1350,  750,    2250,   "us",          LIVE,   "TPA: throttle where the cut starts"),
    # --- rates (Betaflight "actual")
    ("roll_rc_rate",         7,    1,     255,   "10 deg/s",    LIVE,   "roll centre sensitivity"),
    ("pitch_rc_rate",        7,    1,     255,   "10 deg/s",    LIVE,   "pitch centre sensitivity"),
    ("yaw_rc_rate",          7,    1,     255,   "10 deg/s",    LIVE,   "yaw centre sensitivity"),
    ("roll_srate",          67,    0,     200,   "10 deg/s",    LIVE,   "roll max rate"),
    ("pitch_srate",         67,    0,     200,   "10 deg/s",    LIVE,   "pitch max rate"),
    ("yaw_srate",           67,    0,     200,   "10 deg/s",    LIVE,   "yaw max rate"),
    ("roll_expo",            0,    0,     100,   "%",           LIVE,   "roll expo"),
    ("pitch_expo",           0,    0,     100,   "%",           LIVE,   "pitch expo"),
    ("yaw_expo",             0,    0,     100,   "%",           LIVE,   "yaw expo"),
    # --- angle and horizon (the PIFF shape of seed 002)
    ("angle_limit",         60,    5,      90,   "deg",         LIVE,   "angle mode: tilt at full stick (seed 001: 5)"),
    ("angle_p_gain",        50,    0,     300,   "0.1/s",       LIVE,   "angle mode: deg/s of rate per 0.1 deg of error"),
    ("angle_ff",            50,    0,     200,   "%",           LIVE,   "angle mode: feed-forward of the angle setpoint's speed"),
    ("angle_rate_limit",   500,   50,    2000,   "deg/s",       LIVE,   "angle mode: largest rate setpoint"),
    ("horizon_level",   50,    0,     100,   "%",           LIVE,   "horizon: levelling strength at centre stick"),
    ("yaw_hold",             0,    0,       1,   "",            LIVE,   "yaw stick centred: hold the heading it was centred at (seed 001 holds yaw)"),
    ("yaw_hold_p",         2.0,  0.1,    20.0,   "1/s",         LIVE,   "heading hold: yaw rate per radian of heading error"),
    # --- fixed wing: PIFF, modes, launch (INAV's names and scales; core/stages/fwcontrol.py, core/command/launch.py)
    ("fw_p_roll",            5,    0,     200,   "",            LIVE,   "plane roll rate P (INAV scale)"),
    ("fw_i_roll",            7,    0,     200,   "",            LIVE,   "plane roll rate I (INAV scale)"),
    ("fw_ff_roll",          50,    0,     200,   "",            LIVE,   "plane roll feed-forward: most of the aileron for a commanded rate"),
    ("fw_p_pitch",           5,    0,     200,   "",            LIVE,   "plane pitch rate P (INAV scale)"),
    ("fw_i_pitch",           7,    0,     200,   "",            LIVE,   "plane pitch rate I (INAV scale)"),
    ("fw_ff_pitch",         50,    0,     200,   "",            LIVE,   "plane pitch feed-forward"),
    ("fw_p_yaw",             6,    0,     200,   "",            LIVE,   "plane yaw rate P (INAV scale)"),
    ("fw_i_yaw",            10,    0,     200,   "",            LIVE,   "plane yaw rate I (INAV scale)"),
    ("fw_ff_yaw",           60,    0,     200,   "",            LIVE,   "plane yaw feed-forward"),
    ("fw_p_level",          20,    0,     200,   "",            LIVE,   "plane ANGLE: rate per angle error (INAV scale: deg/s per deg x 6.56)"),
    ("fw_iterm_limit",     165,    0,     500,   "",            LIVE,   "plane I-term limit, INAV fw_iterm_throw_limit (500 = full throw)"),
    ("fw_roll_dps",        180,   10,    1800,   "deg/s",       LIVE,   "plane ACRO full-stick roll rate, and ANGLE's roll rate limit (INAV roll_rate x 10)"),
    ("fw_pitch_dps",        90,   10,    1800,   "deg/s",       LIVE,   "plane ACRO full-stick pitch rate, and ANGLE's pitch rate limit"),
    ("fw_yaw_dps",          60,   10,    1800,   "deg/s",       LIVE,   "plane ACRO full-stick yaw rate"),
    ("fw_max_bank_deg",     45,    5,      80,   "deg",         LIVE,   "plane ANGLE: bank at full stick (INAV max_angle_inclination_rll)"),
    ("fw_max_pitch_deg",    20,    5,      80,   "deg",         LIVE,   "plane ANGLE: pitch at full stick (INAV max_angle_inclination_pit)"),
    ("fw_turn_yaw_gain",   1.0,  0.0,     2.0,   "",            LIVE,   "plane turn coordination: rudder for the turn's yaw rate (INAV fw_turn_assist_yaw_gain)"),
    ("fw_turn_pit_gain",   1.0,  0.0,     2.0,   "",            LIVE,   "plane turn coordination: nose-up rate in a bank (INAV fw_turn_assist_pitch_gain)"),
    ("fw_ref_speed_m_s",  15.0,  3.0,    60.0,   "m/s",         LIVE,   "plane airspeed the turn coordination assumes (INAV fw_reference_airspeed)"),
    ("fw_tpa_rate",          0,    0,     100,   "%",           LIVE,   "plane TPA: how much of INAV's throttle scaling of the gains (0.3..2x) applies"),
    ("fw_tpa_bp_us",      1500, 1000,    2000,   "us",          LIVE,   "plane TPA breakpoint: throttle where the gains are as set (INAV tpa_breakpoint)"),
    ("manual_rc_expo",      70,    0,     100,   "%",           LIVE,   "plane MANUAL: stick expo"),
    ("manual_roll_pct",    100,    0,     100,   "%",           LIVE,   "plane MANUAL: aileron throw at full stick (INAV manual_roll_rate)"),
    ("manual_pitch_pct",   100,    0,     100,   "%",           LIVE,   "plane MANUAL: elevator throw at full stick (INAV manual_pitch_rate)"),
    ("manual_yaw_pct",     100,    0,     100,   "%",           LIVE,   "plane MANUAL: rudder throw at full stick (INAV manual_yaw_rate)"),
    ("manual_ch",            0,    0,      18,   "ch",          LIVE,   "plane MANUAL mode switch channel, 0 = none (takes priority over angle and horizon)"),
    ("manual_min_us",     1700,  900,    2100,   "us",          LIVE,   "MANUAL mode range start"),
    ("manual_max_us",     2100,  900,    2100,   "us",          LIVE,   "MANUAL mode range end"),
    ("fw_autolaunch",        0,    0,       1,   "",            LIVE,   "plane: every arm on the ground starts a hand launch (INAV FW_AUTOLAUNCH)"),
    ("launch_acc_m_s2",   18.6,  5.0,    60.0,   "m/s2",        LIVE,   "hand launch: forward acceleration of a throw (INAV nav_fw_launch_accel)"),
    ("launch_vel_m_s",     3.0,  0.5,    20.0,   "m/s",         LIVE,   "hand launch: speed the throw must give (INAV nav_fw_launch_velocity)"),
    ("launch_detect_ms",    40,   10,    1000,   "ms",          LIVE,   "hand launch: the acceleration held this long (INAV nav_fw_launch_detect_time)"),
    ("launch_max_deg",      45,    5,      90,   "deg",         LIVE,   "hand launch: most tilt a throw may have (INAV nav_fw_launch_max_angle)"),
    ("launch_delay_ms",    500,    0,    5000,   "ms",          LIVE,   "hand launch: motor start after the throw (INAV nav_fw_launch_motor_delay)"),
    ("launch_idle_us",    1000, 1000,    1400,   "us",          LIVE,   "hand launch: throttle before the motor start (INAV nav_fw_launch_idle_thr)"),
    ("launch_thr_us",     1700, 1000,    2000,   "us",          LIVE,   "hand launch: climb throttle (INAV nav_fw_launch_thr)"),
    ("launch_climb_deg",    18,    0,      45,   "deg",         LIVE,   "hand launch: climb pitch (INAV nav_fw_launch_climb_angle)"),
    ("launch_time_ms",    5000, 1000,   60000,   "ms",          LIVE,   "hand launch: the climb ends this long after the throw (INAV nav_fw_launch_timeout)"),
    ("fs_glide_pitch",    -3.0, -20.0,    5.0,   "deg",         LIVE,   "plane failsafe glide (stage 2): pitch held, wings level, motor off"),
    # --- receiver and pilot input
    ("rc_smoothing_hz",     40,    0,     250,   "Hz",          LIVE,   "setpoint smoothing (PT2), 0 = off"),
    ("deadband",             5,    0,      32,   "us",          LIVE,   "roll/pitch stick deadband around centre"),
    ("yaw_deadband",         5,    0,     100,   "us",          LIVE,   "yaw stick deadband around centre"),
    ("min_check",         1050,  750,    2250,   "us",          LIVE,   "throttle below this counts as low"),
    ("rc_map",       12435678, 12345678, 87654321, "",         LIVE,   "receiver channel per function, digits roll pitch yaw throttle AUX1-4 (CLI map: AETR1234 = 12435678)"),
    ("arm_ch",               5,    0,      18,   "ch",          LIVE,   "arm switch channel (AUX1 = 5), 0 = none"),
    ("arm_min_us",        1700,  900,    2100,   "us",          LIVE,   "arm switch range start"),
    ("arm_max_us",        2100,  900,    2100,   "us",          LIVE,   "arm switch range end"),
    ("angle_ch",             6,    0,      18,   "ch",          LIVE,   "angle mode switch channel, 0 = none"),
    ("angle_min_us",      1300,  900,    2100,   "us",          LIVE,   "angle mode range start"),
    ("angle_max_us",      2100,  900,    2100,   "us",          LIVE,   "angle mode range end"),
    ("horizon_ch",           6,    0,      18,   "ch",          LIVE,   "horizon mode switch channel, 0 = none"),
    ("horizon_min_us",    1300,  900,    2100,   "us",          LIVE,   "horizon mode range start"),
    ("horizon_max_us",    1700,  900,    2100,   "us",          LIVE,   "horizon mode range end (takes priority over angle)"),
    ("airmode_ch",           0,    0,      18,   "ch",          LIVE,   "air mode switch channel; 0 = none: the airmode parameter decides"),
    ("airmode_min_us",    1700,  900,    2100,   "us",          LIVE,   "air mode range start (with airmode_ch set, air mode only in range)"),
    ("airmode_max_us",    2100,  900,    2100,   "us",          LIVE,   "air mode range end"),
    ("fs_switch_ch",         0,    0,      18,   "ch",          LIVE,   "failsafe test switch channel (Betaflight FAILSAFE box), 0 = none"),
    ("fs_switch_min_us",  1700,  900,    2100,   "us",          LIVE,   "failsafe switch range start"),
    ("fs_switch_max_us",  2100,  900,    2100,   "us",          LIVE,   "failsafe switch range end"),
    ("fs_switch_mode", "stage1",   0,       0,   FS_SWITCH_MODES, LIVE, "failsafe switch: stage1 = as a lost receiver, stage2 = procedure now, kill = disarm"),
    # --- arming and failsafe
    ("disarm_frames",        5,    1,      50,   "frames",      LIVE,   "switch must read disarm this many frames in a row"),
    ("boot_grace_ms",     1000,    0,   30000,   "ms",          LIVE,   "no arming this long after boot"),
    ("airmode_thr_pct",   25,    0,     100,   "%",           LIVE,   "air mode and I-term start once throttle passes this"),
    ("imu_stale_ms",        20,    2,     500,   "ms",          LIVE,   "no IMU sample this long = IMU fault"),
    ("rx_timeout_ms",      100,   20,    1000,   "ms",          LIVE,   "no good frame this long = link lost"),
    ("fs_delay_ms",  400,    0,   10000,   "ms",          LIVE,   "stage 1 (hold, levelled) lasts this long"),
    ("fs_procedure", "land", 0,      0,    FAILSAFE_PROCEDURES, LIVE, "stage 2: drop, land or glide"),
    ("fs_throttle", 1300, 1000,    2000,   "us",          LIVE,   "throttle while failsafe lands"),
    ("fs_land_max_ms",   20000, 1000,  120000,   "ms",          LIVE,   "failsafe landing disarms after this at the latest"),
    ("fs_land_m_s",        1.0,  0.2,     5.0,   "m/s",         LIVE,   "failsafe landing: descent speed once a hover throttle is known"),
    ("arm_source",     "range",    0,       0,   ARM_SOURCES,   LIVE,   "arm by the AUX range, or seed001: arm_ch above 1500 us"),
    ("vbat_min_cell",      3.3,  0.0,     4.2,   "V",           LIVE,   "no arming below this per cell (cells auto-detected), 0 = off"),
    ("crash_time_ms",     1000,    0,   10000,   "ms",          LIVE,   "armed, tipped over, still and throttle low this long = crash: disarm; 0 = off"),
    # --- receiver wire (protocol, link watch, telemetry)
    ("rx_provider",     "crsf",    0,       0,   ("crsf", "sbus", "ibus", "ppm", "pwm"), REBOOT, "receiver protocol (Betaflight serialrx_provider; ppm/pwm: pin edges)"),
    ("rx_pwm_channels",      6,    1,      16,   "ch",          REBOOT, "pwm receiver: channels captured, one pin each (FS-IA6: 6)"),
    ("crsf_telemetry",       1,    0,       1,   "",            LIVE,   "CRSF: send battery, attitude and flight mode back to the receiver"),
    ("rc_smooth_type",   "pt2",    0,       0,   ("pt2", "pt1", "alphabeta"), LIVE, "stick smoothing: PT2/PT1 at rc_smoothing_hz, or seed 001's alpha-beta"),
    ("ab_thr_alpha",       0.1,  0.0,     1.0,   "",            LIVE,   "alpha-beta filter, throttle stick: position gain per pass"),
    ("ab_thr_beta",      0.005,  0.0,     1.0,   "",            LIVE,   "alpha-beta filter, throttle stick: velocity gain per pass"),
    ("ab_roll_alpha",      0.1,  0.0,     1.0,   "",            LIVE,   "alpha-beta filter, roll stick: position gain per pass"),
    ("ab_roll_beta",     0.005,  0.0,     1.0,   "",            LIVE,   "alpha-beta filter, roll stick: velocity gain per pass"),
    ("ab_pitch_alpha",     0.1,  0.0,     1.0,   "",            LIVE,   "alpha-beta filter, pitch stick: position gain per pass"),
    ("ab_pitch_beta",    0.005,  0.0,     1.0,   "",            LIVE,   "alpha-beta filter, pitch stick: velocity gain per pass"),
    ("ab_yaw_alpha",       0.1,  0.0,     1.0,   "",            LIVE,   "alpha-beta filter, yaw stick: position gain per pass"),
    ("ab_yaw_beta",      0.005,  0.0,     1.0,   "",            LIVE,   "alpha-beta filter, yaw stick: velocity gain per pass"),
    ("thr_mode",         "raw",    0,       0,   ("raw", "bands"), LIVE, "throttle: raw stick percentage (seed 004) or seed 001's three bands"),
    ("thr_descend_us",    1350, 1000,    2000,   "us",          LIVE,   "bands: throttle while the stick is below 1333 us (DESCEND)"),
    ("thr_hover_us",      1500, 1000,    2000,   "us",          LIVE,   "bands: throttle while the stick is 1333..1665 us (HOVERING)"),
    ("thr_climb_us",      1650, 1000,    2000,   "us",          LIVE,   "bands: throttle while the stick is 1666 us and up (CLIMB)"),
    # --- motor and servo outputs (protocol, output failsafe, motor test)
    ("motor_protocol", "dshot600", 0,      0,    ("dshot150", "dshot300", "dshot600", "dshot1200", "oneshot125",
                                                  "oneshot42", "multishot", "pwm"), REBOOT, "ESC protocol of the motor outputs"),
    ("dshot_bidir",          0,    0,       1,   "",            REBOOT, "bidirectional DShot: ESCs answer each frame with eRPM"),
    ("motor_poles",         14,    2,     255,   "",            LIVE,   "motor magnet poles: RPM = eRPM / (poles / 2)"),
    ("motor_pwm_rate",     480,   50,   40000,   "Hz",          REBOOT, "PWM/OneShot/Multishot update rate"),
    ("motor_order",          0,    0, 87654321,  "",            REBOOT, "output per motor as digits (2143: motor 1 on output 2), 0 = in order"),
    ("motor_reversed",       0,    0,     255,   "",            REBOOT, "DShot: bit k reverses motor k+1 (spin-direction command at boot)"),
    ("output_fs_ms",       100,   10,    1000,   "ms",          LIVE,   "no fresh motor command this long: every output to its disarmed value"),
    ("motor_enable",       255,    0,     255,   "",            LIVE,   "bit k: motor k+1 runs; a cleared bit keeps it stopped (seed 001 commands 8-11)"),
    ("motor1_min_us",     1000, 1000,    2000,   "us",          LIVE,   "motor 1 lowest armed command, PWM scale (raised to the idle output)"),
    ("motor1_max_us",     2000, 1000,    2000,   "us",          LIVE,   "motor 1 highest command, PWM scale (lowered to motor_max_pct)"),
    ("motor2_min_us",     1000, 1000,    2000,   "us",          LIVE,   "motor 2 lowest armed command, PWM scale"),
    ("motor2_max_us",     2000, 1000,    2000,   "us",          LIVE,   "motor 2 highest command, PWM scale"),
    ("motor3_min_us",     1000, 1000,    2000,   "us",          LIVE,   "motor 3 lowest armed command, PWM scale"),
    ("motor3_max_us",     2000, 1000,    2000,   "us",          LIVE,   "motor 3 highest command, PWM scale"),
    ("motor4_min_us",     1000, 1000,    2000,   "us",          LIVE,   "motor 4 lowest armed command, PWM scale"),
    ("motor4_max_us",     2000, 1000,    2000,   "us",          LIVE,   "motor 4 highest command, PWM scale"),
    ("motor_test_pct",    30.0,  0.0,   100.0,   "%",           LIVE,   "motor test: highest output allowed"),
    ("servo_pwm_rate",      50,   50,     333,   "Hz",          REBOOT, "servo output rate"),
    # servos 0..3 (the boards' servo lines; servo 0 is a tricopter's tail) as INAV's `servo N min max mid
    # rate`, and 8 `smix` rules (docs/fixed-wing.md): a rule with rate 0 is unused; with every rate 0 the
    # mixer_type's preset applies. A row costs a 32-bit port about 135 bytes of heap: no more than the boards use.
    ("servo0_min_us",     1000,  500,    2500,   "us",          LIVE,   "servo 0 end point at full negative travel (INAV servo min)"),
    ("servo0_mid_us",     1500,  500,    2500,   "us",          LIVE,   "servo 0 centre, its trim: disarmed and failsafe position"),
    ("servo0_max_us",     2000,  500,    2500,   "us",          LIVE,   "servo 0 end point at full positive travel (INAV servo max)"),
    ("servo0_rate",        100, -125,     125,   "%",           LIVE,   "servo 0 rate, negative = reversed (INAV servo rate)"),
    ("servo1_min_us",     1000,  500,    2500,   "us",          LIVE,   "servo 1 low end point"),
    ("servo1_mid_us",     1500,  500,    2500,   "us",          LIVE,   "servo 1 centre and trim: disarmed and failsafe position"),
    ("servo1_max_us",     2000,  500,    2500,   "us",          LIVE,   "servo 1 high end point"),
    ("servo1_rate",        100, -125,     125,   "%",           LIVE,   "servo 1 rate, negative = reversed"),
    ("servo2_min_us",     1000,  500,    2500,   "us",          LIVE,   "servo 2 low end point"),
    ("servo2_mid_us",     1500,  500,    2500,   "us",          LIVE,   "servo 2 centre and trim: disarmed and failsafe position"),
    ("servo2_max_us",     2000,  500,    2500,   "us",          LIVE,   "servo 2 high end point"),
    ("servo2_rate",        100, -125,     125,   "%",           LIVE,   "servo 2 rate, negative = reversed"),
    ("servo3_min_us",     1000,  500,    2500,   "us",          LIVE,   "servo 3 low end point"),
    ("servo3_mid_us",     1500,  500,    2500,   "us",          LIVE,   "servo 3 centre and trim: disarmed and failsafe position"),
    ("servo3_max_us",     2000,  500,    2500,   "us",          LIVE,   "servo 3 high end point"),
    ("servo3_rate",        100, -125,     125,   "%",           LIVE,   "servo 3 rate, negative = reversed"),
    ("smix0_servo",           0,    0,       3,   "",            LIVE,   "servo mixer rule 0 (smix): the servo it moves, 0..3"),
    ("smix0_input",           0,    0,      28,   "",            LIVE,   "rule 0: input, INAV's source id (0..3 stabilised roll pitch yaw throttle, 4.. RC)"),
    ("smix0_rate",            0, -125,     125,   "%",           LIVE,   "rule 0: weight of the input, negative reverses; 0 = rule unused"),
    ("smix0_speed",           0,    0,     255,   "10us/s",      LIVE,   "rule 0: speed limit of the input in 10 us/s, 0 = none"),
    ("smix1_servo",           0,    0,       3,   "",            LIVE,   "smix rule 1: servo"),
    ("smix1_input",           0,    0,      28,   "",            LIVE,   "smix rule 1: input source id"),
    ("smix1_rate",            0, -125,     125,   "%",           LIVE,   "smix rule 1: weight, 0 = unused"),
    ("smix1_speed",           0,    0,     255,   "10us/s",      LIVE,   "smix rule 1: speed limit, 0 = none"),
    ("smix2_servo",           0,    0,       3,   "",            LIVE,   "smix rule 2: servo"),
    ("smix2_input",           0,    0,      28,   "",            LIVE,   "smix rule 2: input source id"),
    ("smix2_rate",            0, -125,     125,   "%",           LIVE,   "smix rule 2: weight, 0 = unused"),
    ("smix2_speed",           0,    0,     255,   "10us/s",      LIVE,   "smix rule 2: speed limit, 0 = none"),
    ("smix3_servo",           0,    0,       3,   "",            LIVE,   "smix rule 3: servo"),
    ("smix3_input",           0,    0,      28,   "",            LIVE,   "smix rule 3: input source id"),
    ("smix3_rate",            0, -125,     125,   "%",           LIVE,   "smix rule 3: weight, 0 = unused"),
    ("smix3_speed",           0,    0,     255,   "10us/s",      LIVE,   "smix rule 3: speed limit, 0 = none"),
    ("smix4_servo",           0,    0,       3,   "",            LIVE,   "smix rule 4: servo"),
    ("smix4_input",           0,    0,      28,   "",            LIVE,   "smix rule 4: input source id"),
    ("smix4_rate",            0, -125,     125,   "%",           LIVE,   "smix rule 4: weight, 0 = unused"),
    ("smix4_speed",           0,    0,     255,   "10us/s",      LIVE,   "smix rule 4: speed limit, 0 = none"),
    ("smix5_servo",           0,    0,       3,   "",            LIVE,   "smix rule 5: servo"),
    ("smix5_input",           0,    0,      28,   "",            LIVE,   "smix rule 5: input source id"),
    ("smix5_rate",            0, -125,     125,   "%",           LIVE,   "smix rule 5: weight, 0 = unused"),
    ("smix5_speed",           0,    0,     255,   "10us/s",      LIVE,   "smix rule 5: speed limit, 0 = none"),
    ("smix6_servo",           0,    0,       3,   "",            LIVE,   "smix rule 6: servo"),
    ("smix6_input",           0,    0,      28,   "",            LIVE,   "smix rule 6: input source id"),
    ("smix6_rate",            0, -125,     125,   "%",           LIVE,   "smix rule 6: weight, 0 = unused"),
    ("smix6_speed",           0,    0,     255,   "10us/s",      LIVE,   "smix rule 6: speed limit, 0 = none"),
    ("smix7_servo",           0,    0,       3,   "",            LIVE,   "smix rule 7: servo"),
    ("smix7_input",           0,    0,      28,   "",            LIVE,   "smix rule 7: input source id"),
    ("smix7_rate",            0, -125,     125,   "%",           LIVE,   "smix rule 7: weight, 0 = unused"),
    ("smix7_speed",           0,    0,     255,   "10us/s",      LIVE,   "smix rule 7: speed limit, 0 = none"),
    # --- autopilot link and built-in test
    ("ap_ch",                7,    0,      18,   "ch",          LIVE,   "autopilot mode switch channel (AUX3 = 7), 0 = no autopilot"),
    ("ap_min_us",         1700,  900,    2100,   "us",          LIVE,   "autopilot switch range start"),
    ("ap_max_us",         2100,  900,    2100,   "us",          LIVE,   "autopilot switch range end"),
    ("ap_timeout_ms",      200,   20,    5000,   "ms",          LIVE,   "no MSP RC this long = autopilot silent: pilot or failsafe flies"),
    ("ap_override_pct",     10,    1,     100,   "%",           LIVE,   "pilot roll/pitch stick beyond this replaces the autopilot's"),
    ("maint_override",       0,    0,       1,   "",            LIVE,   "seed-001 radio override flies, replacing the receiver (link timeout = rx_timeout_ms); 0 = seed 004 rules"),
    # --- configuration links (CLI, MSP, maintenance protocol, storage)
    ("serial_update_hz",   100,  100,    2000,   "Hz",          REBOOT, "configuration links task rate (MSP, CLI, maintenance; Betaflight serial_update_rate_hz), above loop_hz = every pass"),
    # --- flight log
    ("blackbox_rate_hz",  1000,    0,    8000,   "Hz",          LIVE,   "flight-log rate of the fast topics, capped at loop_hz (replay needs loop_hz); 0 = off"),
    # --- board (rp2 pins and devices)
    ("imu_type",     "mpu6050",    0,      0,    ("mpu6050", "bno055", "lsm9ds1", "icm42688", "auto"), REBOOT, "rp2 board: the IMU to start (auto = probe I2C)"),
    ("rx_core1",             0,    0,       1,   "",            REBOOT, "rp2 board: parse the serial receiver on the second core (lock-free handover to the loop)"),
)
# fmt: on

_NAME = 0
_DEFAULT = 1
_MIN = 2
_MAX = 3
_UNIT = 4


def _index():
    index = {}
    for i, row in enumerate(PARAMS):
        index[row[_NAME]] = i
    return index


INDEX = _index()


def row(name):
    """The table row for `name`, or None."""
    i = INDEX.get(name)
    return None if i is None else PARAMS[i]


def is_choice(r):
    return isinstance(r[_DEFAULT], str)


_APPLIES = 5

# Other names every surface accepts for a parameter (Betaflight's, where hoverfly's differ), with
# the unit conversion: table value = given value * factor. resolve() is the one place names are
# looked up, so the CLI, `--set`, MSP, the maintenance protocol, storage and the scenario and
# airframe files all take the same names.
ALIASES = {
    "gyro_lpf1_static_hz": ("gyro_lpf1_hz", 1),
    "gyro_lpf2_static_hz": ("gyro_lpf2_hz", 1),
    "rpm_filter_harmonics": ("rpm_harmonics", 1),
    "rpm_filter_min_hz": ("rpm_min_hz", 1),
    "rpm_filter_fade_range_hz": ("rpm_fade_hz", 1),
    "dterm_lpf1_static_hz": ("dterm_lpf1_hz", 1),
    "anti_gravity_gain": ("ag_gain", 1),
    "anti_gravity_cutoff_hz": ("ag_cutoff_hz", 1),
    "anti_gravity_p_gain": ("ag_p_gain", 1),
    "align_board_roll": ("board_roll_deg", 1),
    "align_board_pitch": ("board_pitch_deg", 1),
    "align_board_yaw": ("board_yaw_deg", 1),
    "horizon_level_strength": ("horizon_level", 1),
    "airmode_start_throttle_percent": ("airmode_thr_pct", 1),
    "yaw_motors_reversed": ("yaw_motors_rev", 1),
    "iterm_relax_cutoff": ("iterm_relax_hz", 1),
    "failsafe_throttle": ("fs_throttle", 1),
    "failsafe_procedure": ("fs_procedure", 1),
    "failsafe_switch_mode": ("fs_switch_mode", 1),
    "motor_pwm_protocol": ("motor_protocol", 1),
    "serialrx_provider": ("rx_provider", 1),
    "dshot_idle_value": ("motor_idle_pct", 0.01),  # Betaflight: percent x 100
    "failsafe_delay": ("fs_delay_ms", 100),  # Betaflight: tenths of a second
    "max_angle_inclination_rll": ("fw_max_bank_deg", 0.1),  # INAV: tenths of a degree
    "max_angle_inclination_pit": ("fw_max_pitch_deg", 0.1),
    "fw_iterm_throw_limit": ("fw_iterm_limit", 1),
    "fw_turn_assist_yaw_gain": ("fw_turn_yaw_gain", 1),
    "fw_turn_assist_pitch_gain": ("fw_turn_pit_gain", 1),
    "fw_reference_airspeed": ("fw_ref_speed_m_s", 0.01),  # INAV: cm/s
    "manual_roll_rate": ("manual_roll_pct", 1),
    "manual_pitch_rate": ("manual_pitch_pct", 1),
    "manual_yaw_rate": ("manual_yaw_pct", 1),
    "nav_fw_launch_accel": ("launch_acc_m_s2", 0.01),  # INAV: cm/s2
    "nav_fw_launch_velocity": ("launch_vel_m_s", 0.01),  # INAV: cm/s
    "nav_fw_launch_detect_time": ("launch_detect_ms", 1),
    "nav_fw_launch_max_angle": ("launch_max_deg", 1),
    "nav_fw_launch_motor_delay": ("launch_delay_ms", 1),
    "nav_fw_launch_idle_thr": ("launch_idle_us", 1),
    "nav_fw_launch_thr": ("launch_thr_us", 1),
    "nav_fw_launch_climb_angle": ("launch_climb_deg", 1),
    "nav_fw_launch_timeout": ("launch_time_ms", 1),
    "gyro_calib_duration": ("gyro_cal_ms", 10),  # Betaflight: hundredths of a second
    "serial_update_rate_hz": ("serial_update_hz", 1),  # seed 004: `set serial_update_rate_hz = 2000`
    # the one servo's end points before per-servo rows (a tricopter's tail is servo 0): old saves and scripts
    "servo_min_us": ("servo0_min_us", 1),
    "servo_mid_us": ("servo0_mid_us", 1),
    "servo_max_us": ("servo0_max_us", 1),
}

_HUGE = 1000000000000000  # 1e15: a whole number past this is shown as "huge" (CPython cannot str() 10**5000)


def resolve(name):
    """(table name, factor) for a table name or an alias in any case, or (None, 1). Never raises."""
    if not isinstance(name, str):
        return None, 1
    if name in INDEX:
        return name, 1
    key = name.strip().lower()
    if key in INDEX:
        return key, 1
    a = ALIASES.get(key)
    if a is not None and a[0] in INDEX:
        return a
    return None, 1


def show(value):
    """`value` for a one-line reason: short, printable, never raises."""
    try:
        if value is None:
            return "nothing"
        if isinstance(value, bool):
            return "true" if value else "false"
        if isinstance(value, int):
            if value > _HUGE or value < -_HUGE:
                return "a huge number" if value > 0 else "a huge negative number"
            return "%d" % value
        if isinstance(value, float):
            return "%.6g" % value
        if not isinstance(value, str):
            return "a %s" % type(value).__name__
        out = ""
        for ch in value[:24]:
            out += ch if " " <= ch <= "~" else "?"
        return out + ("..." if len(value) > 24 else "")
    except Exception:
        return "that value"


def _distance(a, b, limit):
    """Edit distance of a and b if it is at most limit, else limit + 1. Only a band of 2 * limit + 1
    cells per row is computed, in two reused rows: the error path stays a few milliseconds on a Pico."""
    n = len(b)
    big = limit + 1
    prev = [j if j <= limit else big for j in range(n + 1)]
    cur = [big] * (n + 1)
    for i in range(1, len(a) + 1):
        lo = i - limit if i > limit else 1
        hi = i + limit if i + limit < n else n
        cur[0] = i if i <= limit else big
        if lo > 1:
            cur[lo - 1] = big
        best = cur[0]
        ai = a[i - 1]
        for j in range(lo, hi + 1):
            d = prev[j - 1] + (0 if ai == b[j - 1] else 1)
            x = prev[j] + 1
            if x < d:
                d = x
            x = cur[j - 1] + 1
            if x < d:
                d = x
            if d > big:
                d = big
            cur[j] = d
            if d < best:
                best = d
        if hi < n:
            cur[hi + 1] = big
        if best > limit:
            return big
        prev, cur = cur, prev
    return prev[n] if prev[n] <= limit else big


def _near_pass(w, candidates, limit, found, found_d):
    for c in candidates:
        if len(c) - len(w) > limit or len(w) - len(c) > limit:
            continue
        # a typo keeps the first, second or last letter: the others are not worth a distance
        if c[0] != w[0] and c[-1] != w[-1] and (len(c) < 2 or len(w) < 2 or c[1] != w[1]):
            continue
        d = _distance(w, c, found_d if found_d <= limit else limit)
        if d < found_d or (d == found_d and d <= limit and found is not None and c < found):
            found = c
            found_d = d
    return found, found_d


def nearest(word, candidates=None):
    """The candidate (table names and aliases by default) nearest to `word` by edit distance, within 2
    edits (3 for a name of 9 letters or more) and sharing its first, second or last letter; else None.
    Ties go to the alphabetically first, so the answer does not hang on dict order. Only on the error
    path: one pass over the table without building a list, a banded distance for the few that pass."""
    if not isinstance(word, str):
        return None
    w = word.strip().lower()
    if not w or len(w) > 40:
        return None
    limit = 2 if len(w) < 9 else 3
    if candidates is None:
        found, found_d = _near_pass(w, INDEX, limit, None, limit + 1)
        return _near_pass(w, ALIASES, limit, found, found_d)[0]
    return _near_pass(w, candidates, limit, None, limit + 1)[0]


def unknown_reason(name):
    """The one-line reason for a name that is no parameter, with the nearest one if there is one."""
    if not isinstance(name, str):
        return "a parameter name is text, not %s" % show(name)
    guess = nearest(name)
    if guess is None:
        return "unknown parameter '%s'" % show(name)
    return "unknown parameter '%s' (did you mean %s?)" % (show(name), guess)


def _number(value):
    """A finite int or float from a number or its text, or None (bools count as 0/1)."""
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, str):
        text = value.strip()
        try:
            return int(text)
        except ValueError:
            pass
        try:
            value = float(text)
        except ValueError:
            return None
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        # inf - inf and nan - nan are nan: the one finite test that is the same on every port
        return value if value - value == 0.0 else None
    return None


def _check_row(r, name, value):
    if is_choice(r):
        choices = r[_UNIT]
        if isinstance(value, str):
            low = value.strip().lower()
            for c in choices:
                if c.lower() == low:
                    return c, None
        elif isinstance(value, int) and not isinstance(value, bool) and 0 <= value < len(choices):
            return choices[value], None
        return None, "%s must be one of %s, not %s" % (name, ", ".join(choices), show(value))
    lo = r[_MIN]
    hi = r[_MAX]
    whole = isinstance(r[_DEFAULT], int)
    v = _number(value)
    if v is None:
        kind = "whole number" if whole else "number"
        return None, "%s must be a finite %s from %s to %s, not %s" % (name, kind, lo, hi, show(value))
    if v < lo or v > hi:
        return None, "%s = %s is out of range %s .. %s" % (name, show(v), lo, hi)
    if whole:
        if isinstance(v, float):
            if v != int(v):
                return None, "%s must be a whole number from %d to %d, not %s" % (name, lo, hi, show(v))
            v = int(v)
    else:
        v = float(v)
    extra = _EXTRA_CHECKS.get(name)
    if extra is not None:
        err = extra(v)
        if err is not None:
            return None, err
    return v, None


def check(name, value):
    """(table name, value as stored, None) if `value` may be stored under `name` (a table name or
    an alias, converted by the alias's factor), else (None, None, one-line reason). The one check
    every surface goes through. Never raises, whatever `name` and `value` are."""
    try:
        key, factor = resolve(name)
        if key is None:
            return None, None, unknown_reason(name)
        r = PARAMS[INDEX[key]]
        if factor != 1:
            v = _number(value)
            if v is None:
                return None, None, "%s must be a finite number, not %s" % (show(name), show(value))
            v = v * factor
            if isinstance(r[_DEFAULT], int) and v - v == 0.0 and -_HUGE < v < _HUGE:
                v = int(v + 0.5) if v >= 0 else int(v - 0.5)
            value = v
        v, err = _check_row(r, key, value)
        if err is not None:
            if factor != 1:
                err = "%s sets %s x %g: %s" % (show(name), key, factor, err)
            return None, None, err
        return key, v, None
    except Exception:  # SAFETY: no value may raise into a server, the boot or a slow task
        return None, None, "%s: value %s not understood" % (show(name), show(value))


def check_value(name, value):
    """(value, None) if `value` may be stored under `name` (converted for the table name it
    resolves to: see check()), else (None, one-line reason)."""
    _, v, err = check(name, value)
    return v, err


def rc_map_error(value):
    """None when rc_map's eight digits name each receiver channel 1..8 once (a permutation), else why not."""
    seen = 0
    rest = value
    for _ in range(8):
        d = rest % 10
        if d < 1 or d > 8 or seen & (1 << d):
            return "rc_map = %d must name each channel 1..8 once (e.g. 12435678 = map AETR1234)" % value
        seen |= 1 << d
        rest //= 10
    return None


# Checks a range cannot express, per parameter: fn(value) -> None or the one-line reason.
_EXTRA_CHECKS = {"rc_map": rc_map_error}


def smix_input_error(value):
    """None for a servo-mixer input hoverfly has, else why not: INAV's 12, 13 (gimbal) and 14 (flaps) are not."""
    if 12 <= value <= 14:
        return "smix input %d (%s) is not supported: inputs are 0..11 and 15..28" % (
            value, "flaps" if value == 14 else "gimbal")
    return None


for _i in range(8):
    _EXTRA_CHECKS["smix%d_input" % _i] = smix_input_error


class Params:
    """The live values, keyed by name; starts from the table's defaults.

    `values` is what the stages read (get). Before boot every accepted write lands there. From
    latch_boot() (Flight.start) on, a write to a REBOOT row lands in `pending` instead: it is stored,
    saved and shown, and applies at the next boot; the running stages keep what they booted with
    (a frame, loop rate or protocol changed under a running loop is a crash, not a setting)."""

    def __init__(self):
        self.values = {}
        self.pending = {}  # REBOOT rows written after boot: name -> value for the next boot
        self.booted = False
        self.load_skipped = []  # names Storage.load skipped at boot (the built-in test's params check)
        self.changed = 0  # bumped on every accepted write; stages re-read on change
        # Called with no arguments after every accepted write (the flight log: it logs the change
        # after the pass it came in, without looking at `changed` every pass).
        self.on_change = None
        self.reset()

    def _bump(self):
        self.changed += 1
        if self.on_change is not None:
            self.on_change()

    def _store(self, name, v):
        if self.booted and PARAMS[INDEX[name]][_APPLIES] == REBOOT:
            if v == self.values[name]:
                if name in self.pending:
                    del self.pending[name]
            else:
                self.pending[name] = v
            return
        self.values[name] = v

    def latch_boot(self):
        """A flight boots on these values (Flight.start): REBOOT rows still waiting from an earlier
        boot apply now (the firmware bridge boots new flights on the same Params), and those written
        from now on wait for the next boot. Returns True if every stored value loaded (the built-in
        test's params check)."""
        for name in self.pending:
            self.values[name] = self.pending[name]
        self.pending = {}
        self.booted = True
        return not self.load_skipped

    def reset(self):
        for r in PARAMS:
            self._store(r[_NAME], r[_DEFAULT])
        self._bump()

    def get(self, name):
        """The value the stages run with (a REBOOT row: the one it booted with)."""
        return self.values[name]

    def stored(self, name):
        """The value as stored and saved: a REBOOT row's pending value, else the running one."""
        if name in self.pending:
            return self.pending[name]
        return self.values[name]

    def saved_values(self):
        """name -> value as the next boot should see them (what Storage.save writes)."""
        out = dict(self.values)
        for name in self.pending:
            out[name] = self.pending[name]
        return out

    def set(self, name, value):
        """Store `value` under `name` (a table name or an alias); returns None on success or the
        one-line reason it was refused (nothing changed)."""
        key, value, err = check(name, value)
        if err is None and key == "fs_procedure" and value == "glide" and not is_plane(self.stored("mixer_type")):
            # Only a plane glides. (A stored glide loaded on a multirotor, through update(), lands it: Failsafe.)
            err = ("fs_procedure = glide is a plane's failsafe (mixer_type airplane, flying_wing or vtail); "
                   "a %s cannot glide: use land or drop" % self.stored("mixer_type"))
        if err is not None:
            return err
        self._store(key, value)
        self._bump()
        return None

    def update(self, pairs):
        """Set several (name, value) pairs; all or nothing. Returns None or the first reason."""
        checked = []
        for name, value in pairs:
            key, v, err = check(name, value)
            if err is not None:
                return err
            checked.append((key, v))
        for key, v in checked:
            self._store(key, v)
        self._bump()
        return None

    def diff(self):
        """(name, value as stored) for every value that differs from its default, in table order."""
        out = []
        for r in PARAMS:
            v = self.stored(r[_NAME])
            if v != r[_DEFAULT]:
                out.append((r[_NAME], v))
        return out
