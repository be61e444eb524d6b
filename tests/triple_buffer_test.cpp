// The servo/worker hand-off: newest value wins, nothing is torn, and both sides never wait.

#include "gshaptics/device/triple_buffer.h"

#include <gtest/gtest.h>

#include <thread>

namespace gshaptics {
namespace {

struct Message {
  std::uint64_t seq = 0;
  std::uint64_t payload[15] = {};  // all equal to seq * 7 when not torn
};

TEST(TripleBuffer, ReadIfNewOnlyAfterAWrite) {
  TripleBuffer<int> b(-1);
  int v = 0;
  EXPECT_FALSE(b.read_if_new(v));
  EXPECT_EQ(b.read(), -1);
  b.write(5);
  EXPECT_TRUE(b.read_if_new(v));
  EXPECT_EQ(v, 5);
  EXPECT_FALSE(b.read_if_new(v));
  EXPECT_EQ(b.read(), 5);
}

TEST(TripleBuffer, NewestValueWinsAfterSeveralWrites) {
  TripleBuffer<int> b;
  for (int i = 1; i <= 10; ++i) b.write(i);
  int v = 0;
  ASSERT_TRUE(b.read_if_new(v));
  EXPECT_EQ(v, 10);
  b.write(11);
  b.write(12);
  EXPECT_EQ(b.read(), 12);
  EXPECT_EQ(b.read(), 12);
}

TEST(TripleBuffer, TwoThreadsNeverTearAndNeverGoBack) {
  TripleBuffer<Message> b;
  constexpr std::uint64_t kWrites = 2'000'000;
  std::thread writer([&] {
    Message m;
    for (std::uint64_t s = 1; s <= kWrites; ++s) {
      m.seq = s;
      for (auto& p : m.payload) p = s * 7;
      b.write(m);
    }
  });
  std::uint64_t last = 0, reads = 0, torn = 0, backwards = 0;
  Message m;
  while (last < kWrites) {
    if (!b.read_if_new(m)) continue;
    ++reads;
    for (auto p : m.payload) torn += p != m.seq * 7 ? 1 : 0;
    backwards += m.seq <= last ? 1 : 0;
    last = m.seq;
  }
  writer.join();
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(backwards, 0u);
  EXPECT_EQ(last, kWrites);
  EXPECT_GT(reads, 1u);
}

}  // namespace
}  // namespace gshaptics
