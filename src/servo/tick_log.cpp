#include "gshaptics/servo/tick_log.h"

#include <cstdio>

#include "gshaptics/io/atomic_file.h"
#include "gshaptics/servo/safety.h"

namespace gshaptics {

namespace {

/// One column: its name, its group and how a record prints into it.
struct Column {
  const char* name;
  unsigned group;
  int (*print)(char* out, std::size_t size, const TickRecord& r);
};

#define GSH_COL(name, group, fmt, expr) \
  {name, group, [](char* o, std::size_t n, const TickRecord& r) { return std::snprintf(o, n, fmt, expr); }}

// The one declaration of the log's columns, in log order. The device's motion is written to
// round-trip precision (%.17g): a replay of the log (replay:LOG) feeds the renderer the very
// samples the run did; rounded to 1 nm and 0.1 um/s, the seen proxy's spot and phase choices
// drifted apart over a contact and ended it a few ticks early (0.96 N at a 17 N peak).
const Column kColumns[] = {
    GSH_COL("time_s", kColumnsMotion, "%.6f", r.time),
    GSH_COL("x", kColumnsMotion, "%.17g", r.position.x()),
    GSH_COL("y", kColumnsMotion, "%.17g", r.position.y()),
    GSH_COL("z", kColumnsMotion, "%.17g", r.position.z()),
    GSH_COL("vx", kColumnsMotion, "%.17g", r.velocity.x()),
    GSH_COL("vy", kColumnsMotion, "%.17g", r.velocity.y()),
    GSH_COL("vz", kColumnsMotion, "%.17g", r.velocity.z()),
    GSH_COL("candidates", kColumnsQuery, "%u", r.counts.candidates),
    GSH_COL("prefiltered", kColumnsQuery, "%u", r.counts.prefiltered),
    GSH_COL("contacts", kColumnsQuery, "%u", r.counts.contacts),
    GSH_COL("fx", kColumnsForce, "%.5f", r.force.x()),
    GSH_COL("fy", kColumnsForce, "%.5f", r.force.y()),
    GSH_COL("fz", kColumnsForce, "%.5f", r.force.z()),
    GSH_COL("user_fx", kColumnsForce, "%.5f", r.user_force.x()),
    GSH_COL("user_fy", kColumnsForce, "%.5f", r.user_force.y()),
    GSH_COL("user_fz", kColumnsForce, "%.5f", r.user_force.z()),
    GSH_COL("query_us", kColumnsQuery, "%.2f", double(r.query_us)),
    GSH_COL("desired_fx", kColumnsServo, "%.5f", r.desired.x()),
    GSH_COL("desired_fy", kColumnsServo, "%.5f", r.desired.y()),
    GSH_COL("desired_fz", kColumnsServo, "%.5f", r.desired.z()),
    GSH_COL("jitter_us", kColumnsServo, "%.2f", double(r.jitter_us)),
    GSH_COL("tick_us", kColumnsServo, "%.2f", double(r.tick_us)),
    GSH_COL("result_age_us", kColumnsServo, "%.1f", double(r.result_age_us)),
    GSH_COL("held", kColumnsServo, "%d", (r.flags & kFlagHeld) ? 1 : 0),
    GSH_COL("fading", kColumnsServo, "%d", (r.flags & (kFlagFading | kFlagFaded)) ? 1 : 0),
    GSH_COL("flags", kColumnsServo, "%u", r.flags),
    GSH_COL("latency_us", kColumnsLatency, "%.1f", double(r.latency_us)),
    GSH_COL("proxy_x", kColumnsProxy, "%.6f", r.proxy.x()),
    GSH_COL("proxy_y", kColumnsProxy, "%.6f", r.proxy.y()),
    GSH_COL("proxy_z", kColumnsProxy, "%.6f", r.proxy.z()),
    GSH_COL("constraints", kColumnsProxy, "%u", unsigned(r.constraints)),
    GSH_COL("energy_j", kColumnsPassivity, "%.7f", r.energy),
    GSH_COL("pc_damping", kColumnsPassivity, "%.4f", double(r.damping)),
    GSH_COL("tx", kColumnsTorque, "%.6f", r.torque.x()),
    GSH_COL("ty", kColumnsTorque, "%.6f", r.torque.y()),
    GSH_COL("tz", kColumnsTorque, "%.6f", r.torque.z()),
    GSH_COL("setpoint_x", kColumnsAdmittance, "%.9f", r.setpoint.x()),
    GSH_COL("setpoint_y", kColumnsAdmittance, "%.9f", r.setpoint.y()),
    GSH_COL("setpoint_z", kColumnsAdmittance, "%.9f", r.setpoint.z()),
};

#undef GSH_COL

}  // namespace

std::string tick_log_header(unsigned columns) {
  std::string h;
  for (const Column& c : kColumns) {
    if ((c.group & columns) == 0) continue;
    if (!h.empty()) h += ',';
    h += c.name;
  }
  return h;
}

void write_tick_log_csv(const std::string& path, std::span<const TickRecord> records, unsigned columns) {
  std::string text = tick_log_header(columns) + "\n";
  text.reserve(records.size() * 260 + text.size());
  char cell[64];
  for (const TickRecord& r : records) {
    bool first = true;
    for (const Column& c : kColumns) {
      if ((c.group & columns) == 0) continue;
      if (!first) text += ',';
      first = false;
      const int n = c.print(cell, sizeof cell, r);
      text.append(cell, std::size_t(n > 0 ? std::min<int>(n, int(sizeof cell) - 1) : 0));
    }
    text += '\n';
  }
  write_file_atomically(path, text);
}

}  // namespace gshaptics
