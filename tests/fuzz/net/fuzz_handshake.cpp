// Both handshake state machines fed fuzzer frames at every step: random
// frames must never authenticate (server) or open (client); the server also
// gets a genuine Hello so the Proof step is reached.
#include <cstdint>
#include <cstdlib>

#include "common/net/handshake.h"

using namespace hemm::net;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  Key psk{};
  psk.fill(5);
  const int mode = data[0] % 4;
  const std::span<const uint8_t> in(data + 1, size - 1);
  Nonce cn{}, sn{};
  cn[0] = 1;
  sn[0] = 2;
  ClientHandshake::Params cp;
  cp.psk = psk;
  cp.client_nonce = cn;
  ServerHandshake::Params sp;
  sp.psk = psk;
  sp.server_nonce = sn;
  sp.session_id = 99;
  ClientHandshake c(cp);
  ServerHandshake s(sp);
  const auto hello = c.start();
  switch (mode) {
    case 0: {  // server, first frame
      const auto st = s.on_frame(in);
      if (st.kind == HandshakeStep::Kind::kAuthenticated) abort();
      break;
    }
    case 1: {  // server, proof step
      if (s.on_frame(hello).kind != HandshakeStep::Kind::kContinue) abort();
      const auto st = s.on_frame(in);
      if (st.kind == HandshakeStep::Kind::kAuthenticated) abort();
      break;
    }
    case 2: {  // client, challenge step
      const auto st = c.on_frame(in);
      if (st.kind == HandshakeStep::Kind::kOpen) abort();
      if (st.kind == HandshakeStep::Kind::kContinue) abort();  // would need the server's proof
      break;
    }
    default: {  // client, welcome step
      const auto ch = s.on_frame(hello);
      if (c.on_frame(ch.reply).kind != HandshakeStep::Kind::kContinue) abort();
      const auto st = c.on_frame(in);
      if (st.kind == HandshakeStep::Kind::kOpen) abort();
      break;
    }
  }
  return 0;
}
