#include "gshaptics/servo/servo_log.h"

#include <algorithm>
#include <cstdio>

#include "gshaptics/servo/safety.h"

namespace gshaptics {

void write_servo_log_csv(const std::string& path, const std::vector<ServoTickRecord>& records) {
  std::string text;
  text.reserve(records.size() * 260 + 400);
  text +=
      "time_s,x,y,z,vx,vy,vz,candidates,prefiltered,contacts,fx,fy,fz,user_fx,user_fy,user_fz,"
      "query_us,desired_fx,desired_fy,desired_fz,jitter_us,tick_us,result_age_us,held,fading,flags\n";
  char line[768];
  for (const auto& r : records) {
    const int n = std::snprintf(
        line, sizeof line,
        "%.6f,%.6f,%.6f,%.6f,%.5f,%.5f,%.5f,%u,%u,%u,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.2f,%.5f,%.5f,"
        "%.5f,%.2f,%.2f,%.1f,%d,%d,%u\n",
        to_seconds(r.time), r.position.x(), r.position.y(), r.position.z(), r.velocity.x(),
        r.velocity.y(), r.velocity.z(), r.counts.candidates, r.counts.prefiltered, r.counts.contacts,
        r.force.x(), r.force.y(), r.force.z(), r.user_force.x(), r.user_force.y(), r.user_force.z(),
        double(r.query_us), r.desired.x(), r.desired.y(), r.desired.z(), double(r.jitter_us),
        double(r.tick_us), double(r.result_age_us), (r.flags & kFlagHeld) ? 1 : 0,
        (r.flags & (kFlagFading | kFlagFaded)) ? 1 : 0, r.flags);
    text.append(line, std::size_t(std::max(0, n)));
  }
  write_file_atomically(path, text);
}

std::vector<TickRecord> to_tick_records(const std::vector<ServoTickRecord>& records) {
  std::vector<TickRecord> out(records.size());
  for (std::size_t i = 0; i < records.size(); ++i) {
    const auto& r = records[i];
    TickRecord& t = out[i];
    t.time = to_seconds(r.time);
    t.position = r.position;
    t.velocity = r.velocity;
    t.counts = r.counts;
    t.force = r.force;
    t.user_force = r.user_force;
    t.query_us = r.query_us;
  }
  return out;
}

}  // namespace gshaptics
