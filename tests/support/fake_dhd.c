/* A stand-in for Force Dimension's libdhd.so exporting the C functions gshaptics looks up, so the
   run-time loading and the DHD device are tested without the vendor's library or hardware.
   Reports two devices. Every call is appended to a log the test reads back (fake_dhd_log), and
   the test sets the device state (fake_dhd_set_*). Units as the DHD API: metres, newtons. */
#include <stdio.h>
#include <string.h>

static char log_buf[1 << 16];
static size_t log_len = 0;
static double pos[3], vel[3], force[3];
static int buttons = 0, force_enabled = 0, fail_reads = 0, reset_mode = 0, opened = -1;

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
void fake_dhd_force(double* f) { f[0] = force[0]; f[1] = force[1]; f[2] = force[2]; }
int fake_dhd_force_enabled(void) { return force_enabled; }

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
  *x = pos[0]; *y = pos[1]; *z = pos[2];
  return 0;
}
int dhdGetLinearVelocity(double* x, double* y, double* z, char id) {
  (void)id;
  if (fail_reads) return -1;
  *x = vel[0]; *y = vel[1]; *z = vel[2];
  return 0;
}
int dhdSetForce(double x, double y, double z, char id) {
  (void)id;
  force[0] = x; force[1] = y; force[2] = z;
  if (x == 0 && y == 0 && z == 0) note("dhdSetForce(0)");
  return 0;
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
  status[0] = 1; /* DHD_STATUS_POWER */
  status[1] = 1; /* DHD_STATUS_CONNECTED */
  status[3] = reset_mode; /* DHD_STATUS_RESET */
  note("dhdGetStatus");
  return 0;
}
const char* dhdGetSystemName(char id) { (void)id; return "fake omega.3"; }
const char* dhdErrorGetLastStr(void) { return "no error"; }
