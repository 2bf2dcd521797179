/* Buffer layouts shared by the kernels and the Python side. Each block repeats constants of
 * one Python module (named there); tests/native checks that the two agree. */
#ifndef NAVK_LAYOUT_H
#define NAVK_LAYOUT_H

/* ins.py: the state buffer Ins.x */
#define X_P 0
#define X_V 3
#define X_Q 6
#define X_C 10
#define X_BG 19
#define X_BA 22
#define X_DVS 25
#define X_AN 28
#define X_WIE 31
#define X_PK 34
#define X_TH 37
#define X_THP 40
#define X_DVP 43
#define X_DT 46
#define X_HDT 47
#define X_G0 48
#define X_INV_RN 49
#define X_INV_RM 50
#define X_H0 51
#define NX 52

/* eskf.py: the float buffer Eskf.e and the int buffer Eskf.i */
#define N 15
#define MAX_SCALARS 8
#define MAX_NZ 6
#define IDLE 0
#define PROPAGATING 1
#define UPDATING 2
#define S_T 0
#define S_DECAY_G 1
#define S_DECAY_A 2
#define S_S 3
#define S_Y 4
#define S_GATE2 5
#define S_INV_TAU_G 6
#define S_INV_TAU_A 7
#define E_P 0
#define E_A 225
#define E_U 450
#define E_V 465
#define E_K 480
#define E_FN 495
#define E_C 498
#define E_W 507
#define E_S 510
#define E_H 518
#define E_Z 638
#define E_R 646
#define E_DX 654
#define E_Q 669
#define E_LO 684
#define E_HI 699
#define NE 714
#define I_JOB 0
#define I_STEP 1
#define I_M 2
#define I_NSCAL 3
#define I_READY 4
#define I_ACCEPTED 5
#define I_REJECTED 6
#define I_GATE_MASK 7
#define I_EARTH 8
#define I_NNZ 9
#define I_NZ 17
#define NI 65

/* nav.py: the calibration buffer Navigator._cal */
#define CAL_G 0 /* gyro counts per rad/s */
#define CAL_A 1 /* accel counts per m/s^2 */
#define CAL_GB 2 /* gyro bias (3), rad/s */
#define CAL_AB 5 /* accel bias (3), m/s^2 */
#define CAL_GM 8 /* gyro matrix (9) */
#define CAL_AM 17 /* accel matrix (9) */
#define NCAL 26
#define CAL_HAS_GM 1 /* flags */
#define CAL_HAS_AM 2
/* nav.py: the standstill detector self._st and its parameters self._stp */
#define ST_FX 0
#define ST_VAR 3
#define ST_GYRO 4
#define ST_SPEED 5
#define STP_ALPHA 0
#define STP_ACCEL 1
#define STP_GYRO 2
#define STP_GNSS_SPEED 3
#define STP_MAX_SPEED 4
#define NSTP 5
#define STILL_FIRST 1 /* flags */
#define STILL_GNSS_SPEED 2
#define STILL_NAVIGATING 4
/* eskf.py error-state indices */
#define IX_POS 0
#define IX_VEL 3
#define IX_ATT 6
#define IX_BG 9
#define IX_BA 12
/* frame.py: the int fields of App._frame_ints */
#define F_COUNTER 0
#define F_GYRO_LSB_X10 1
#define F_ACCEL_LSB 2
#define F_PPS 3
#define F_GGA 4
#define F_VALID 5
#define F_HEIGHT_DM 6
#define F_STATE 7
#define F_LAT_DEG 8
#define F_LAT_FRAC 9
#define F_LON_DEG 10
#define F_LON_FRAC 11
#define NF 12
/* records.py: the int fields of the extended frame, ExtFrame.fields */
#define EF_COUNTER 0
#define EF_HEALTH 1
#define EF_STATE 2
#define EF_CONFIG 3
#define EF_FLAGS 4
#define EF_WORST_US 5
#define EF_MEAN_US 6
#define EF_OVERRUNS 7
#define EF_GC_RUNS 8
#define EF_LAT0_E7 9
#define EF_LON0_DEG 10
#define EF_LON0_FRAC 11
#define EF_TICK 12
#define EF_CAUSES 13
#define NEF 14
/* records.py: the int fields of the raw-input record, RawRecord.fields */
#define RF_COUNTER 0
#define RF_T0_US 1
#define RF_PPS_US 2
#define RF_SATURATED 3
#define RF_N 4
#define NRF 5
/* drivers/bmi055.py: the counts that mean over range */
#define BMI055_GYRO_SAT_HI 32766
#define BMI055_GYRO_SAT_LO -32767
#define BMI055_ACCEL_SAT_HI 2046
#define BMI055_ACCEL_SAT_LO -2047
/* geo.py: the origin's coefficients LocalFrame.coef */
#define GEO_H0 0
#define GEO_KE 1
#define GEO_KN 2
#define GEO_GE_N 3
#define GEO_INV_RN 4
#define GEO_GN_N 5
#define GEO_INV_RM 6
#define GEO_GN_E 7
#define GEO_GU_N 8
#define GEO_GU_E 9
#define GEO_SIN_LAT 10
#define GEO_COS_LAT 11
#define GEO_NCOEF 12

/* nav.py: the aiding parameters Navigator._aid */
#define AID_UERE 0 /* m per HDOP */
#define AID_FLOOR 1 /* least 1-sigma position error, m */
#define AID_VERT 2 /* vertical / horizontal sigma */
#define AID_VEL_SIGMA 3 /* m/s */
#define AID_ZUPT_SIGMA 4 /* m/s */
#define AID_NHC_SIGMA 5 /* m/s */
#define AID_LEVER 6 /* IMU -> antenna, body, m (3) */
#define AID_HDOP_MAX 9 /* worst HDOP accepted, assumed when unknown */
#define AID_REANCHOR 10 /* re-anchoring distance, m */
#define AID_FAULT_SIGMA 11 /* health 2 beyond this east or north 1-sigma, m */
#define AID_FAULT_SIGMA_V 12 /* ... or this vertical 1-sigma, m */
#define AID_HEADING_V 13 /* the course is the heading from this speed, m/s */
#define NAID 14
/* nav.py: a fix in ints, Navigator.fix_in, and fix_check's result bits */
#define FI_LAT_E7 0
#define FI_LON_DEG 1
#define FI_LON_FRAC 2
#define FI_ALT_MM 3
#define FI_QUALITY 4
#define FI_HDOP_X100 5
#define FI_SPEED_MM_S 6
#define FI_COURSE_CDEG 7
#define FI_TICK 8
#define FI_NO_HEIGHT 1073741823 /* 0x3FFFFFFF */
#define NFI 9
#define FC_USABLE 1
#define FC_SPEED 2
#define FC_REANCHOR 4
#define FC_MOVING 8
#define FC_COURSE 16
#define FC_FAST 32
/* nav.py: the pending fix self._fx and the used fix self._used */
#define FX_H 0
#define FX_HDOP 1
#define FX_SPEED 2
#define FX_COURSE 3
#define FX_SIG_H 4
#define FX_SIG_V 5
#define US_P 0
#define US_SPEED 3
#define US_COURSE 4
#define US_SIG_H 5
#define US_SIG_V 6

/* nav.py: the control state Navigator._c (ints), its option bits, the filter jobs, nav_tick's
 * results, and the states */
#define C_TICK 0
#define C_STATE 1
#define C_HEALTH 2
#define C_STILL 3
#define C_N_STILL 4
#define C_SAT_UNTIL 5
#define C_FAULT_UNTIL 6
#define C_GATED_UNTIL 7
#define C_SPEED_TICK 8
#define C_ACCEPT_TICK 9
#define C_REJECTS 10
#define C_SINCE_PROP 11
#define C_SINCE_ZUPT 12
#define C_SINCE_NHC 13
#define C_JOB 14
#define C_FIX_PENDING 15
#define C_FIX_QUEUED 16
#define C_PHASE 17
#define C_BUSY 18
#define C_FIX_TICK 19
#define C_USED_TICK 20
#define C_UPDATES 21
#define C_FIX_LAT 22
#define C_FIX_LON_DEG 23
#define C_FIX_LON_FRAC 24
#define C_FIX_QUALITY 25
#define C_LAST_FIX_TICK 26
#define C_N_LEVEL 27
#define C_LEVELED 28
#define C_N_STABLE 29
#define C_TRK_SET 30
#define C_TRK_TICK 31
#define C_T_SECOND 32
#define C_T_STILL 33
#define C_T_TIMEOUT 34
#define C_T_PROP 35
#define C_T_ZUPT 36
#define C_T_NHC 37
#define C_T_LEVEL 38
#define C_T_TRACK 39
#define C_T_LATENCY 40
#define C_SLICES 41
#define C_RESET_AFTER 42
#define C_OPTS 43
#define C_CAL_FLAGS 44
#define C_MIN_QUALITY 45
#define C_IMU_STATUS 46
#define C_V_REJECTS 47
#define C_CAUSES 48
#define C_UNCERTAIN 49
#define C_N_HELD 50
#define C_N_SAME_G 51
#define C_N_SAME_A 52
#define C_PREV_G 53
#define C_PREV_A 56
#define C_T_STUCK 59
#define C_HELD_UNTIL 60
#define C_DEAD_UNTIL 61
#define C_RESET_UNTIL 62
#define C_DATA_UNTIL 63
#define C_INFLATE 64
#define C_DRIFT_UNTIL 65
#define C_LAG_TICK 66
#define C_IMPLAUSIBLE_UNTIL 67
#define C_PREV_FIX 68
#define C_JUMPED 71
#define C_LAST_TICK 72
#define C_FROZEN 73
#define C_T_STAMP_LAG 74
#define NC 75
/* nav.py: the navigator's float buffers in one, Navigator.mem */
#define M_X 0
#define M_E 52
#define M_YPR 766
#define M_W 769
#define M_F 772
#define M_CAL 775
#define M_ST 801
#define M_STP 807
#define M_CORR 812
#define M_RING_P 818
#define M_RING_V 1202
#define M_GP 1586
#define M_FX 1589
#define M_US 1595
#define M_AID 1602
#define M_INIT 1616
#define M_NS 1631
#define M_LVL 1634
#define M_BW 1640
#define M_CN 1645
#define M_LAST 1654
#define M_LS 1656
#define M_BS 1704
#define M_AW 1709
#define NM 1711
/* nav.py: the aiding watch, m + M_AW, its result bits, and C_INFLATE's bits */
#define AW_LAT 0
#define AW_UP 1
#define AW_HIT_LAT 1
#define AW_HIT_UP 2
#define INFLATE_MOTION 1
#define INFLATE_VERTICAL 2
/* nav.py: the receiver's unseen error and the fixes' lag, m + M_CN (_consistency, _lag_search) */
#define CN_K 0
#define CN_MH 1
#define CN_MV 2
#define CN_VH 3
#define CN_VV 4
#define CN_KL 5
#define CN_LAG 6
#define CN_LAGT 7
#define CN_RK 8
#define NCN 9
/* nav.py: the lag search, m + M_LS (_lag_search) */
#define LS_C 16
#define LS_STEP 4
#define LS_E 0
#define LS_N 16
#define LS_M 32
#define NLS 48
#define OPT_ZUPT 1
#define OPT_NHC 2
#define OPT_CONING 4
#define OPT_LAG 8
#define JOB_NONE 0
#define JOB_GNSS 1
#define JOB_AID 2
#define EV_ALIGN 1
#define EV_FIX 2
#define EV_RESET 3
#define EV_FAULT 4
#define EV_VRESET 5
#define IMU_OVER_RANGE 0x3F /* the IMU driver's status word */
#define IMU_FRESH 0x1C0
#define IMU_REPEAT 0x200 /* the app's: a missed tick's repeat of the last sample */
#define CAUSE_IMU_SAT 0x1 /* health's causes */
#define CAUSE_IMU_HELD 0x2
#define CAUSE_IMU_DEAD 0x4
#define CAUSE_NUMERIC 0x8
#define CAUSE_GNSS_LOST 0x10
#define CAUSE_GNSS_GATED 0x20
#define CAUSE_GNSS_REJECTS 0x40
#define CAUSE_GNSS_DATA 0x80
#define CAUSE_RESET 0x100
#define CAUSE_UNCERTAIN 0x200
#define CAUSE_DRIFT 0x400
#define CAUSE_GNSS_IMPLAUSIBLE 0x20000
#define CAUSE_NOT_NAVIGATING 0x80000
#define CAUSE_FAULTS 0x2074C
#define ALIGNING 1
#define NAVIGATING 2
#define RING 128

/* drivers/gnss.py: the NMEA parser's int buffer Nmea._s (framing state, the sentence's fields:
 * NS_A..NS_F per type, as gnss.py lists) and nmea_scan's results */
#define NMEA_MAXLEN 100 /* line bytes; the comma table follows them in the byte buffer */
#define NMEA_MAXF 40
#define NS_I 0 /* next byte of the input */
#define NS_K 1 /* characters in the line, -1 outside a sentence */
#define NS_X 2 /* running XOR */
#define NS_STAR 3 /* index of '*', -1 before it */
#define NS_NF 4 /* fields found */
#define NS_LEN 5 /* length of the line that ended last */
#define NS_TALKER 6
#define NS_UTC 7
#define NS_POS 8
#define NS_LAT 9
#define NS_DEG 10
#define NS_FRAC 11
#define NS_A 12
#define NS_B 13
#define NS_C 14
#define NS_D 15
#define NS_E 16
#define NS_F 17
#define NS_N 18
#define NR_GGA 1
#define NR_RMC 2
#define NR_VTG 3
#define NR_GSA 4
#define NR_IGNORED 5
#define NR_BAD_FIELD 6
#define NR_NO_CSUM 7
#define NR_MALFORMED 8
#define NR_BAD_CSUM 9
#define NR_OVERLONG 10
#define NR_COLLIDED 11

#endif
