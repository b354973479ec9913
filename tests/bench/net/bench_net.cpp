// Costs of the link's hot paths: sealing/opening datagrams and frames
// (ChaCha20-Poly1305), the replay window, the clock estimator and the
// newest-wins mailbox. The datagram benchmarks repeat 5 times and print
// mean, median and standard deviation (the spread beside the time); their
// Arg is the payload size (1156 bytes: the largest that fits a datagram).
#include <benchmark/benchmark.h>
#include <sodium.h>

#include "common/net/clock_sync.h"
#include "common/net/datagram.h"
#include "common/net/framing.h"
#include "common/concurrency/newest_mailbox.h"
#include "common/net/replay_window.h"
#include "common/net/stream_receiver.h"

namespace hemm::net {
namespace {

Key bench_key() {
  Key k{};
  k.fill(1);
  return k;
}

void BM_SealDatagram(benchmark::State& st) {
  const Key k = bench_key();
  std::vector<uint8_t> payload(static_cast<size_t>(st.range(0)), 0x55), out;
  out.reserve(kMaxDatagramBytes);
  uint64_t seq = 1;
  for (auto _ : st) {
    encode_datagram(k, DatagramHeader{1, seq++, 0}, payload, &out);
    benchmark::DoNotOptimize(out.data());
  }
  st.SetBytesProcessed(static_cast<int64_t>(st.iterations()) * st.range(0));
}
BENCHMARK(BM_SealDatagram)->Arg(16)->Arg(256)->Arg(1156)->Repetitions(5)->ReportAggregatesOnly(true);

void BM_OpenDatagram(benchmark::State& st) {
  // decode_datagram: layout checks + AEAD open, no replay window or parse.
  const Key k = bench_key();
  std::vector<uint8_t> d, plain;
  plain.reserve(kMaxDatagramPayloadBytes);
  encode_datagram(k, DatagramHeader{1, 7, 0}, std::vector<uint8_t>(static_cast<size_t>(st.range(0)), 0x55), &d);
  DatagramHeader h;
  for (auto _ : st) benchmark::DoNotOptimize(decode_datagram(d, 1, k, &h, &plain));
  st.SetBytesProcessed(static_cast<int64_t>(st.iterations()) * st.range(0));
}
BENCHMARK(BM_OpenDatagram)->Arg(16)->Arg(256)->Arg(1156)->Repetitions(5)->ReportAggregatesOnly(true);

// For comparison: the bare keyed BLAKE2b-128 tag over header + payload that
// protocol 1 put on every datagram (authentication only, payload in clear).
void BM_Blake2bTagOnlyProtocol1(benchmark::State& st) {
  const Key k = bench_key();
  std::vector<uint8_t> d(kDatagramHeaderBytes + static_cast<size_t>(st.range(0)), 0x55);
  uint8_t tag[16];
  for (auto _ : st) {
    crypto_generichash(tag, sizeof tag, d.data(), d.size(), k.data(), k.size());
    benchmark::DoNotOptimize(tag);
  }
  st.SetBytesProcessed(static_cast<int64_t>(st.iterations()) * st.range(0));
}
BENCHMARK(BM_Blake2bTagOnlyProtocol1)->Arg(16)->Arg(256)->Arg(1156)->Repetitions(5)->ReportAggregatesOnly(true);

void BM_ReceiveDatagram(benchmark::State& st) {
  // Full receive path: decode + AEAD open + replay window + protobuf parse.
  const Key k = bench_key();
  wire::StreamMessage m;
  m.mutable_heartbeat()->set_period_ms(50);
  const std::string p = m.SerializeAsString();
  StreamReceiver rx(1024);
  rx.open(1, k);
  uint64_t seq = 1;
  std::vector<uint8_t> d;
  DatagramHeader h;
  wire::StreamMessage out;
  for (auto _ : st) {
    st.PauseTiming();
    encode_datagram(k, DatagramHeader{1, seq++, 0}, std::span(reinterpret_cast<const uint8_t*>(p.data()), p.size()), &d);
    st.ResumeTiming();
    benchmark::DoNotOptimize(rx.receive(d, &h, &out));
  }
}
BENCHMARK(BM_ReceiveDatagram)->Repetitions(5)->ReportAggregatesOnly(true);

void BM_RejectForgedDatagram(benchmark::State& st) {
  const Key k = bench_key();
  Key wrong = k;
  wrong[0] ^= 1;
  std::vector<uint8_t> d;
  encode_datagram(wrong, DatagramHeader{1, 1, 0}, std::vector<uint8_t>(64, 1), &d);
  StreamReceiver rx(1024);
  rx.open(1, k);
  DatagramHeader h;
  wire::StreamMessage out;
  for (auto _ : st) benchmark::DoNotOptimize(rx.receive(d, &h, &out));
}
BENCHMARK(BM_RejectForgedDatagram)->Repetitions(5)->ReportAggregatesOnly(true);

void BM_SealOpenFrame(benchmark::State& st) {
  const Key k = bench_key();
  FrameSealer tx(k);
  FrameOpener rx(k);
  std::vector<uint8_t> payload(static_cast<size_t>(st.range(0)), 0x33), inner;
  for (auto _ : st) {
    auto s = tx.seal(payload);
    benchmark::DoNotOptimize(rx.open(s, &inner));
  }
  st.SetBytesProcessed(static_cast<int64_t>(st.iterations()) * st.range(0));
}
BENCHMARK(BM_SealOpenFrame)->Arg(64)->Arg(65536);

void BM_ReplayWindowInOrder(benchmark::State& st) {
  ReplayWindow w(1024);
  uint64_t s = 1;
  for (auto _ : st) benchmark::DoNotOptimize(w.accept(s++));
}
BENCHMARK(BM_ReplayWindowInOrder);

void BM_ClockEstimatorAdd(benchmark::State& st) {
  ClockOffsetEstimator e;
  int64_t t = 0;
  for (auto _ : st) {
    t += 50000000;
    e.add(t, t + 100000000, t + 100100000, t + 200100000);
  }
}
BENCHMARK(BM_ClockEstimatorAdd);

void BM_MailboxPublishTake(benchmark::State& st) {
  NewestMailbox<std::array<double, 32>> mb;
  std::array<double, 32> v{};
  for (auto _ : st) {
    v[0] += 1;
    mb.publish(v);
    benchmark::DoNotOptimize(mb.take());
  }
}
BENCHMARK(BM_MailboxPublishTake);

}  // namespace
}  // namespace hemm::net

BENCHMARK_MAIN();
