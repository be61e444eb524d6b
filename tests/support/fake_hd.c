/* A stand-in for 3D Systems' libHD.so (OpenHaptics HD API) exporting the C functions gshaptics
   looks up. Its "scheduler" is a thread calling the scheduled callback every millisecond, as the
   real servo loop does. Calls are logged (fake_hd_log) and the device state is set by the test
   (fake_hd_set_*). Units as the HD API: millimetres, newtons. */
#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

typedef unsigned int HHD;
typedef unsigned int HDenum;
typedef struct { unsigned int errorCode; int internalErrorCode; HHD hHD; } HDErrorInfo;
typedef unsigned int (*HDCallback)(void*);

static pthread_mutex_t mu = PTHREAD_MUTEX_INITIALIZER;
static char log_buf[1 << 16];
static size_t log_len = 0;
static double pos_mm[3], vel_mm[3], force[3];
static int buttons = 0, calibration = 0x5000, in_frame = 0, frame_errors = 0;
static unsigned long force_writes = 0, nonzero_force_writes = 0;
static HDCallback cb = 0;
static void* cb_data = 0;
static volatile int sched_running = 0;
static pthread_t sched;
static HHD current = 0xFFFFFFFFu;

static void note(const char* s) {
  pthread_mutex_lock(&mu);
  size_t n = strlen(s);
  if (log_len + n + 2 < sizeof log_buf) {
    memcpy(log_buf + log_len, s, n);
    log_len += n;
    log_buf[log_len++] = ' ';
    log_buf[log_len] = 0;
  }
  pthread_mutex_unlock(&mu);
}

/* Test hooks. */
const char* fake_hd_log(void) { return log_buf; }
void fake_hd_set_position_mm(double x, double y, double z) {
  pthread_mutex_lock(&mu); pos_mm[0] = x; pos_mm[1] = y; pos_mm[2] = z; pthread_mutex_unlock(&mu);
}
void fake_hd_set_velocity_mm(double x, double y, double z) {
  pthread_mutex_lock(&mu); vel_mm[0] = x; vel_mm[1] = y; vel_mm[2] = z; pthread_mutex_unlock(&mu);
}
void fake_hd_set_buttons(int b) { buttons = b; }
void fake_hd_set_calibration(int c) { calibration = c; }
void fake_hd_force(double* f) { pthread_mutex_lock(&mu); memcpy(f, force, sizeof force); pthread_mutex_unlock(&mu); }
unsigned long fake_hd_force_writes(void) { return force_writes; }
int fake_hd_frame_errors(void) { return frame_errors; }

/* The HD API (hd.h). */
HHD hdInitDevice(const char* name) { (void)name; note("hdInitDevice"); current = 1; return current; }
void hdDisableDevice(HHD h) { (void)h; note("hdDisableDevice"); current = 0xFFFFFFFFu; }
HDErrorInfo hdGetError(void) { HDErrorInfo e = {0, 0, current}; return e; }
void hdBeginFrame(HHD h) { (void)h; if (in_frame) frame_errors++; in_frame = 1; }
void hdEndFrame(HHD h) { (void)h; if (!in_frame) frame_errors++; in_frame = 0; }
void hdGetDoublev(HDenum what, double* v) {
  pthread_mutex_lock(&mu);
  switch (what) {
    case 0x2050: memcpy(v, pos_mm, sizeof pos_mm); break;          /* HD_CURRENT_POSITION */
    case 0x2051: memcpy(v, vel_mm, sizeof vel_mm); break;          /* HD_CURRENT_VELOCITY */
    case 0x2551: {                                                 /* HD_USABLE_WORKSPACE_DIMENSIONS */
      const double ws[6] = {-80, -60, -35, 80, 60, 35};
      memcpy(v, ws, sizeof ws);
      break;
    }
    case 0x2603: v[0] = 3.3; break;                                /* HD_NOMINAL_MAX_FORCE */
    default: break;
  }
  pthread_mutex_unlock(&mu);
}
void hdGetIntegerv(HDenum what, int* v) {
  if (what == 0x2000) *v = buttons;         /* HD_CURRENT_BUTTONS */
  else if (what == 0x2600) *v = 1000;       /* HD_UPDATE_RATE */
  else if (what == 0x2555) *v = 1 << 2;     /* HD_CALIBRATION_STYLE: inkwell */
}
void hdSetDoublev(HDenum what, const double* v) {
  if (what != 0x2700) return;               /* HD_CURRENT_FORCE */
  if (!in_frame) frame_errors++;
  pthread_mutex_lock(&mu);
  memcpy(force, v, sizeof force);
  force_writes++;
  if (v[0] != 0 || v[1] != 0 || v[2] != 0) nonzero_force_writes++;
  pthread_mutex_unlock(&mu);
}
void hdEnable(HDenum what) { if (what == 0x4000) note("hdEnable(HD_FORCE_OUTPUT)"); }
HDenum hdCheckCalibration(void) { note("hdCheckCalibration"); return (HDenum)calibration; }
void hdUpdateCalibration(int style) {
  char b[48];
  snprintf(b, sizeof b, "hdUpdateCalibration(%d)", style);
  note(b);
  calibration = 0x5000;
}

static void* run(void* arg) {
  (void)arg;
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  while (sched_running) {
    if (cb && cb(cb_data) == 0) { cb = 0; note("callback-done"); }
    t.tv_nsec += 1000000;
    if (t.tv_nsec >= 1000000000) { t.tv_nsec -= 1000000000; t.tv_sec++; }
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, 0);
  }
  return 0;
}
void hdStartScheduler(void) {
  note("hdStartScheduler");
  sched_running = 1;
  pthread_create(&sched, 0, run, 0);
}
void hdStopScheduler(void) {
  note("hdStopScheduler");
  if (sched_running) { sched_running = 0; pthread_join(sched, 0); }
}
unsigned long hdScheduleAsynchronous(HDCallback f, void* data, unsigned short priority) {
  char b[48];
  snprintf(b, sizeof b, "hdScheduleAsynchronous(%u)", (unsigned)priority);
  note(b);
  cb = f; cb_data = data;
  return 7;
}
void hdUnschedule(unsigned long h) { (void)h; note("hdUnschedule"); cb = 0; }
