/* A stand-in for Force Dimension's libdhd.so with the C functions gshaptics looks up, so the
   run-time loading is tested without the vendor's library. Reports two devices. */
int dhdGetDeviceCount(void) { return 2; }
int dhdOpen(void) { return 0; }
int dhdClose(char id) { (void)id; return 0; }
int dhdGetPosition(double* x, double* y, double* z, char id) { (void)id; *x = *y = *z = 0; return 0; }
int dhdGetLinearVelocity(double* x, double* y, double* z, char id) { (void)id; *x = *y = *z = 0; return 0; }
int dhdSetForce(double x, double y, double z, char id) { (void)x; (void)y; (void)z; (void)id; return 0; }
int dhdGetButton(int index, char id) { (void)index; (void)id; return 0; }
const char* dhdErrorGetLastStr(void) { return "no error"; }
