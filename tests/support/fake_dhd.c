/* A stand-in for Force Dimension's libdhd.so exporting the C functions gshaptics looks up, so the
   run-time loading and the DHD device are tested without the vendor's library or hardware.
   Written from the public DHD SDK header (dhdc.h, SDK 3.2 to 3.17): reports two devices of type
   DHD_DEVICE_OMEGA3 (33), no software force limit (dhdGetMaxForce < 0), and saturates a force
   above its motors' capacity (12 N by default), returning DHD_MOTOR_SATURATED (2) from
   dhdSetForce as the SDK does. A sigma.7-like wrist (fake_dhd_set_active_wrist) saturates a
   torque above fake_dhd_set_torque_saturation the same way; dhdGetMaxTorque reports the
   software torque limit (< 0: none). Every call is appended to a log the test reads back
   (fake_dhd_log), forces are recorded (peak while force is enabled), and the test sets the
   device state (fake_dhd_set_*). Units as the DHD API: metres, newtons. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

static char log_buf[1 << 16];
static size_t log_len = 0;
static double pos[3], vel[3], force[3];
static int buttons = 0, force_enabled = 0, fail_reads = 0, reset_mode = 0, opened = -1, powered = 1;
static int system_type = 33;
static double software_limit = -1, software_torque_limit = -1, torque_saturation = 1e9, saturation = 12.0, peak_seen = 0, io_delay_us = 0;
static int active_wrist = 0;
static double peak_torque_seen = 0;
static double torque[3], frame[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
static unsigned long saturated_writes = 0;

static void io_delay(void) {
  if (io_delay_us > 0) {
    struct timespec t = {0, (long)(io_delay_us * 1000)};
    nanosleep(&t, 0);
  }
}

static void note(const char* s) {
  size_t n = strlen(s);
  if (log_len + n + 2 < sizeof log_buf) {
    memcpy(log_buf + log_len, s, n);
    log_len += n;
    log_buf[log_len++] = ' ';
    log_buf[log_len] = 0;
  }
}

/* Test hooks. */
const char* fake_dhd_log(void) { return log_buf; }
void fake_dhd_clear_log(void) { log_len = 0; log_buf[0] = 0; }
void fake_dhd_set_position(double x, double y, double z) { pos[0] = x; pos[1] = y; pos[2] = z; }
void fake_dhd_set_velocity(double x, double y, double z) { vel[0] = x; vel[1] = y; vel[2] = z; }
void fake_dhd_set_buttons(int b) { buttons = b; }
void fake_dhd_set_fail_reads(int f) { fail_reads = f; }
void fake_dhd_set_reset_mode(int r) { reset_mode = r; }
void fake_dhd_set_powered(int p) { powered = p; }
void fake_dhd_set_system_type(int t) { system_type = t; }
void fake_dhd_set_software_limit(double f) { software_limit = f; }
void fake_dhd_set_saturation(double f) { saturation = f; }
void fake_dhd_set_software_torque_limit(double t) { software_torque_limit = t; }
void fake_dhd_set_torque_saturation(double t) { torque_saturation = t; }
void fake_dhd_set_io_delay_us(double us) { io_delay_us = us; }
double fake_dhd_peak_force(void) { return peak_seen; }
double fake_dhd_peak_torque(void) { return peak_torque_seen; }
unsigned long fake_dhd_saturated_writes(void) { return saturated_writes; }
void fake_dhd_reset_force_stats(void) { peak_seen = 0; peak_torque_seen = 0; saturated_writes = 0; }
void fake_dhd_force(double* f) { f[0] = force[0]; f[1] = force[1]; f[2] = force[2]; }
int fake_dhd_force_enabled(void) { return force_enabled; }
void fake_dhd_set_active_wrist(int on) { active_wrist = on; }
void fake_dhd_torque(double* t) { t[0] = torque[0]; t[1] = torque[1]; t[2] = torque[2]; }
void fake_dhd_set_frame(const double* rows) { /* 9 values, row-major */
  int i;
  for (i = 0; i < 9; ++i) frame[i / 3][i % 3] = rows[i];
}

/* The DHD API (dhdc.h). */
int dhdGetDeviceCount(void) { return 2; }
int dhdOpen(void) { note("dhdOpen"); return 0; }
int dhdOpenID(char index) {
  char b[32];
  snprintf(b, sizeof b, "dhdOpenID(%d)", (int)index);
  note(b);
  opened = index;
  return index;
}
int dhdClose(char id) { (void)id; note("dhdClose"); opened = -1; return 0; }
int dhdGetPosition(double* x, double* y, double* z, char id) {
  (void)id;
  if (fail_reads) return -1;
  io_delay();
  *x = pos[0]; *y = pos[1]; *z = pos[2];
  return 0;
}
int dhdGetLinearVelocity(double* x, double* y, double* z, char id) {
  (void)id;
  if (fail_reads) return -1;
  *x = vel[0]; *y = vel[1]; *z = vel[2];
  return 0;
}
static int apply_force(double x, double y, double z) {
  double m = sqrt(x * x + y * y + z * z);
  int ret = 0;
  if (force_enabled && m > peak_seen) peak_seen = m;
  if (m > saturation) { /* the motors give what they can */
    x *= saturation / m; y *= saturation / m; z *= saturation / m;
    saturated_writes++;
    ret = 2; /* DHD_MOTOR_SATURATED */
  }
  force[0] = x; force[1] = y; force[2] = z;
  return ret;
}
int dhdSetForce(double x, double y, double z, char id) {
  (void)id;
  if (x == 0 && y == 0 && z == 0) note("dhdSetForce(0)");
  return apply_force(x, y, z);
}
int dhdGetButton(int index, char id) { (void)id; return (buttons >> index) & 1; }
int dhdEnableForce(unsigned char on, char id) {
  (void)id;
  force_enabled = on;
  note(on ? "dhdEnableForce(on)" : "dhdEnableForce(off)");
  return 0;
}
int dhdGetStatus(int* status, char id) {
  (void)id;
  int i;
  for (i = 0; i < 17; ++i) status[i] = 0;
  status[0] = powered; /* DHD_STATUS_POWER */
  status[1] = 1; /* DHD_STATUS_CONNECTED */
  status[3] = reset_mode; /* DHD_STATUS_RESET */
  note("dhdGetStatus");
  return 0;
}
const char* dhdGetSystemName(char id) { (void)id; return "fake omega.3"; }
int dhdGetSystemType(char id) { (void)id; return system_type; }
double dhdGetMaxForce(char id) { (void)id; return software_limit; }
double dhdGetMaxTorque(char id) { (void)id; return software_torque_limit; }
const char* dhdErrorGetLastStr(void) { return "no error"; }
/* 6-DoF: dhdHasActiveWrist, dhdSetForceAndTorque (0 or DHD_MOTOR_SATURATED for the force part,
   as dhdSetForce), dhdGetOrientationFrame (identity on a device without a wrist). */
bool dhdHasActiveWrist(char id) { (void)id; return active_wrist != 0; }
int dhdSetForceAndTorque(double fx, double fy, double fz, double tx, double ty, double tz, char id) {
  (void)id;
  if (tx == 0 && ty == 0 && tz == 0 && fx == 0 && fy == 0 && fz == 0) note("dhdSetForceAndTorque(0)");
  double tm = sqrt(tx * tx + ty * ty + tz * tz);
  int ret;
  if (force_enabled && tm > peak_torque_seen) peak_torque_seen = tm;
  if (tm > torque_saturation) { /* the wrist's motors give what they can */
    tx *= torque_saturation / tm; ty *= torque_saturation / tm; tz *= torque_saturation / tm;
  }
  torque[0] = tx; torque[1] = ty; torque[2] = tz;
  ret = apply_force(fx, fy, fz);
  if (tm > torque_saturation) {
    if (ret == 0) saturated_writes++;
    ret = 2; /* DHD_MOTOR_SATURATED */
  }
  return ret;
}
int dhdGetOrientationFrame(double m[3][3], char id) {
  int i, j;
  (void)id;
  if (fail_reads) return -1;
  for (i = 0; i < 3; ++i)
    for (j = 0; j < 3; ++j) m[i][j] = active_wrist ? frame[i][j] : (i == j);
  return 0;
}
