/* A stand-in for 3D Systems' libHD.so (OpenHaptics HD API) exporting the C functions gshaptics
   looks up, written from the public OpenHaptics 3.0 headers (hd.h, hdDefines.h) and the
   behaviour its Programmer's Guide and examples describe. It reports a Touch: 3.3 N nominal peak
   force, 0.88 N nominal continuous force. Its "scheduler" is a thread running the scheduled
   callbacks every millisecond, as the real servo loop does; hdScheduleSynchronous runs its
   callback on that thread and blocks until it is done. Calibration follows the Touch: with the
   inkwell style, a device that needs manual input calibrates only inside a servo frame while its
   stylus is in the inkwell; hdCheckCalibration outside a frame is logged as a misuse. Calls are
   logged (fake_hd_log), forces are recorded (peak, frames above the continuous force), and the
   device state is set by the test (fake_hd_set_*). Units as the HD API: millimetres, newtons. */
#include <math.h>
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
static int calibration_style = 1 << 2, in_inkwell = 0, force_output = 0, output_dof = 3;
static double nominal_max_force = 3.3, nominal_continuous_force = 0.88;
static double peak_force_seen = 0;
static unsigned long force_writes = 0, nonzero_force_writes = 0, over_continuous_frames = 0;
static HDCallback cb = 0;
static void* cb_data = 0;
static pthread_cond_t sync_cv = PTHREAD_COND_INITIALIZER;
static HDCallback sync_cb = 0;
static void* sync_data = 0;
static unsigned int error_code = 0;
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
void fake_hd_set_calibration_style(int s) { calibration_style = s; }
void fake_hd_set_in_inkwell(int i) { in_inkwell = i; }
void fake_hd_set_limits(double peak, double continuous) { nominal_max_force = peak; nominal_continuous_force = continuous; }
void fake_hd_clear_log(void) { pthread_mutex_lock(&mu); log_len = 0; log_buf[0] = 0; pthread_mutex_unlock(&mu); }
/* Largest |force| applied in a frame while force output was enabled, and frames above the nominal
   continuous force, since the last reset. */
double fake_hd_peak_force(void) { double f; pthread_mutex_lock(&mu); f = peak_force_seen; pthread_mutex_unlock(&mu); return f; }
unsigned long fake_hd_over_continuous_frames(void) { return over_continuous_frames; }
void fake_hd_reset_force_stats(void) { pthread_mutex_lock(&mu); peak_force_seen = 0; over_continuous_frames = 0; pthread_mutex_unlock(&mu); }
int fake_hd_force_output(void) { return force_output; }
void fake_hd_force(double* f) { pthread_mutex_lock(&mu); memcpy(f, force, sizeof force); pthread_mutex_unlock(&mu); }
unsigned long fake_hd_force_writes(void) { return force_writes; }
int fake_hd_frame_errors(void) { return frame_errors; }

/* The HD API (hd.h). */
HHD hdInitDevice(const char* name) { (void)name; note("hdInitDevice"); current = 1; return current; }
void hdDisableDevice(HHD h) { (void)h; note("hdDisableDevice"); current = 0xFFFFFFFFu; force_output = 0; }
HDErrorInfo hdGetError(void) { HDErrorInfo e = {error_code, 0, current}; error_code = 0; return e; }
void hdBeginFrame(HHD h) {
  (void)h;
  if (in_frame) frame_errors++;
  in_frame = 1;
  /* The Touch's inkwell calibration: done by the servo loop while the stylus is in the inkwell. */
  if (calibration == 0x5002 && (calibration_style & (1 << 2)) && in_inkwell) calibration = 0x5000;
}
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
    case 0x2602: v[0] = 1.0; break;                                /* HD_NOMINAL_MAX_STIFFNESS, N/mm */
    case 0x2603: v[0] = nominal_max_force; break;                  /* HD_NOMINAL_MAX_FORCE */
    case 0x2604: v[0] = nominal_continuous_force; break;           /* HD_NOMINAL_MAX_CONTINUOUS_FORCE */
    default: break;
  }
  pthread_mutex_unlock(&mu);
}
void hdGetIntegerv(HDenum what, int* v) {
  if (what == 0x2000) *v = buttons;         /* HD_CURRENT_BUTTONS */
  else if (what == 0x2600) *v = 1000;       /* HD_UPDATE_RATE */
  else if (what == 0x2555) *v = calibration_style; /* HD_CALIBRATION_STYLE (default: inkwell) */
  else if (what == 0x2554) *v = output_dof; /* HD_OUTPUT_DOF */
}
void hdSetDoublev(HDenum what, const double* v) {
  if (what != 0x2700) return;               /* HD_CURRENT_FORCE */
  if (!in_frame) frame_errors++;
  pthread_mutex_lock(&mu);
  memcpy(force, v, sizeof force);
  force_writes++;
  if (v[0] != 0 || v[1] != 0 || v[2] != 0) nonzero_force_writes++;
  if (force_output) {
    double m = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (m > peak_force_seen) peak_force_seen = m;
    if (m > nominal_continuous_force + 1e-9) over_continuous_frames++;
  }
  pthread_mutex_unlock(&mu);
}
void hdEnable(HDenum what) { if (what == 0x4000) { note("hdEnable(HD_FORCE_OUTPUT)"); force_output = 1; } }
HDenum hdCheckCalibration(void) {
  note(in_frame ? "hdCheckCalibration" : "hdCheckCalibration(outside a frame)");
  return (HDenum)calibration;
}
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
    pthread_mutex_lock(&mu);
    if (sync_cb) {
      HDCallback f = sync_cb;
      void* d = sync_data;
      pthread_mutex_unlock(&mu);
      f(d);
      pthread_mutex_lock(&mu);
      sync_cb = 0;
      pthread_cond_broadcast(&sync_cv);
    }
    pthread_mutex_unlock(&mu);
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
/* Runs f on the scheduler thread and returns when it is done (hd.h). Without a running
   scheduler the call cannot complete: HD_INVALID_OPERATION, callback not run. */
void hdScheduleSynchronous(HDCallback f, void* data, unsigned short priority) {
  char b[48];
  snprintf(b, sizeof b, "hdScheduleSynchronous(%u)", (unsigned)priority);
  note(b);
  if (!sched_running) { error_code = 0x0102; return; }
  pthread_mutex_lock(&mu);
  sync_cb = f;
  sync_data = data;
  while (sync_cb) pthread_cond_wait(&sync_cv, &mu);
  pthread_mutex_unlock(&mu);
}
unsigned long hdScheduleAsynchronous(HDCallback f, void* data, unsigned short priority) {
  char b[48];
  snprintf(b, sizeof b, "hdScheduleAsynchronous(%u)", (unsigned)priority);
  note(b);
  cb = f; cb_data = data;
  return 7;
}
void hdUnschedule(unsigned long h) { (void)h; note("hdUnschedule"); cb = 0; }
