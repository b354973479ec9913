#!/usr/bin/python3
"""An MCAP reader written from the public specification (https://mcap.dev/spec),
independent of hemm's C++ writer: it checks a file and prints its channels.

Checks: the magic at both ends; the record layout (Header first, Footer last,
Data End between the data and the summary, every record's length inside the
file, only the records each section may hold); every chunk's CRC-32 and
uncompressed size (zstd, lz4 is not read here, or none); every message index
against the messages of its chunk; the Data End CRC-32 (every byte before it);
the footer's offsets and summary CRC-32; the Summary Offset groups; the
Statistics counts and times against the messages counted; the Chunk Index
records against the chunks; every schema of encoding "protobuf" decoded as a
FileDescriptorSet with its message type; and every message decoded with its
channel's schema.

Usage: deploy/mcap_reader.py FILE.mcap [--ticks CSV] [--json OUT]
  --ticks CSV  the /operator/servo ticks decoded: tick,t_ns,fx,fy,fz (end-effector 0)
  --json OUT   the channel list, counts and figures as JSON
Exit 0: the file is valid; 1: it is not (the first problem is printed).
Needs python3-zstandard and python3-protobuf (Debian packages).
"""
import json
import struct
import sys
import zlib

import zstandard
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

MAGIC = b"\x89MCAP0\r\n"
HEADER, FOOTER, SCHEMA, CHANNEL, MESSAGE, CHUNK, MESSAGE_INDEX, CHUNK_INDEX = 1, 2, 3, 4, 5, 6, 7, 8
ATTACHMENT, ATTACHMENT_INDEX, STATISTICS, METADATA, METADATA_INDEX, SUMMARY_OFFSET, DATA_END = 9, 10, 11, 12, 13, 14, 15
DATA_RECORDS = {SCHEMA, CHANNEL, MESSAGE, ATTACHMENT, CHUNK, MESSAGE_INDEX, METADATA}
SUMMARY_RECORDS = {SCHEMA, CHANNEL, CHUNK_INDEX, ATTACHMENT_INDEX, STATISTICS, METADATA_INDEX}
CHUNK_RECORDS = {SCHEMA, CHANNEL, MESSAGE}


class Invalid(Exception):
    pass


def check(cond, why):
    if not cond:
        raise Invalid(why)


class Fields:
    """Little-endian fields of one record body, bounds checked."""

    def __init__(self, data, what):
        self.d, self.at, self.what = data, 0, what

    def take(self, n):
        check(self.at + n <= len(self.d), f"{self.what}: shorter than its fields")
        v = self.d[self.at:self.at + n]
        self.at += n
        return v

    def u8(self):
        return self.take(1)[0]

    def u16(self):
        return struct.unpack("<H", self.take(2))[0]

    def u32(self):
        return struct.unpack("<I", self.take(4))[0]

    def u64(self):
        return struct.unpack("<Q", self.take(8))[0]

    def string(self):
        return self.take(self.u32()).decode("utf-8")

    def prefixed(self, width):
        return self.take(self.u32() if width == 4 else self.u64())

    def rest(self):
        v = self.d[self.at:]
        self.at = len(self.d)
        return v

    def pairs(self, key, value):
        """A Map or Array: a uint32 byte length, then entries."""
        body = Fields(self.prefixed(4), self.what)
        out = []
        while body.at < len(body.d):
            out.append((key(body), value(body)))
        return out


def records(data, start, end, what):
    """(offset, opcode, body) of each record in data[start:end]."""
    at = start
    while at < end:
        check(end - at >= 9, f"{what}: a record header cut short at byte {at}")
        op, length = struct.unpack_from("<BQ", data, at)
        check(length <= end - at - 9, f"{what}: the record at byte {at} (opcode {op:#x}) runs past the end")
        yield at, op, data[at + 9:at + 9 + length]
        at += 9 + length


def parse_schema(b):
    f = Fields(b, "Schema")
    return {"id": f.u16(), "name": f.string(), "encoding": f.string(), "data": f.prefixed(4)}


def parse_channel(b):
    f = Fields(b, "Channel")
    c = {"id": f.u16(), "schema_id": f.u16(), "topic": f.string(), "message_encoding": f.string()}
    c["metadata"] = dict(f.pairs(Fields.string, Fields.string))
    return c


def parse_message(b):
    f = Fields(b, "Message")
    return {"channel_id": f.u16(), "sequence": f.u32(), "log_time": f.u64(), "publish_time": f.u64(),
            "data": f.rest()}


class Mcap:
    def __init__(self, path):
        with open(path, "rb") as fh:
            self.d = fh.read()
        self.schemas, self.channels = {}, {}
        self.counts, self.messages = {}, 0
        self.times = []
        self.chunks = []  # (offset, length, start, end, compressed, uncompressed, index offsets, index length)
        self.decoders = {}
        self.ticks = []
        self.read()

    def define(self, op, body):
        if op == SCHEMA:
            s = parse_schema(body)
            if s["id"] == 0:
                return
            check(self.schemas.get(s["id"], s) == s, f"schema {s['id']} defined twice, differently")
            self.schemas[s["id"]] = s
        elif op == CHANNEL:
            c = parse_channel(body)
            check(c["schema_id"] == 0 or c["schema_id"] in self.schemas,
                  f"channel {c['id']} names schema {c['schema_id']}, not defined before it")
            check(self.channels.get(c["id"], c) == c, f"channel {c['id']} defined twice, differently")
            self.channels[c["id"]] = c

    def message(self, body):
        m = parse_message(body)
        check(m["channel_id"] in self.channels, f"a message on channel {m['channel_id']}, not defined before it")
        self.counts[m["channel_id"]] = self.counts.get(m["channel_id"], 0) + 1
        self.messages += 1
        self.times.append(m["log_time"])
        msg = self.decode(m)
        if self.channels[m["channel_id"]]["topic"] == "/operator/servo":
            w = msg.command[0] if len(msg.command) else None
            self.ticks.append((msg.tick, msg.t_ns, *(list(w.force) if w is not None else [0.0, 0.0, 0.0])))
        return m

    def decode(self, m):
        ch = self.channels[m["channel_id"]]
        check(ch["message_encoding"] == "protobuf", f"{ch['topic']}: message encoding {ch['message_encoding']!r}")
        cls = self.decoders.get(ch["schema_id"])
        if cls is None:
            s = self.schemas[ch["schema_id"]]
            check(s["encoding"] == "protobuf", f"schema {s['name']}: encoding {s['encoding']!r}, not protobuf")
            fds = descriptor_pb2.FileDescriptorSet.FromString(s["data"])
            pool = descriptor_pool.DescriptorPool()
            for f in fds.file:
                pool.Add(f)
            desc = pool.FindMessageTypeByName(s["name"])
            if hasattr(message_factory, "GetMessageClass"):  # protobuf >= 4.22
                cls = message_factory.GetMessageClass(desc)
            else:  # Debian 12's 3.21 (python 4.21)
                cls = message_factory.MessageFactory(pool).GetPrototype(desc)
            self.decoders[ch["schema_id"]] = cls
        msg = cls()
        msg.ParseFromString(m["data"])  # raises DecodeError on bytes that are not the type
        # Round trip: the decoded message serializes to the very bytes stored.
        check(msg.SerializeToString() == m["data"], f"{ch['topic']}: message {m['sequence']} does not round-trip")
        return msg

    def chunk(self, at, body):
        f = Fields(body, "Chunk")
        start, end, size, crc = f.u64(), f.u64(), f.u64(), f.u32()
        compression = f.string()
        data = f.prefixed(8)
        check(f.at == len(body), f"the chunk at byte {at} has bytes past its fields")
        if compression == "zstd":
            plain = zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        elif compression == "":
            plain = data
        else:
            raise Invalid(f"the chunk at byte {at}: compression {compression!r} is not read here")
        check(len(plain) == size, f"the chunk at byte {at}: {len(plain)} bytes uncompressed, it says {size}")
        check(crc == 0 or zlib.crc32(plain) == crc, f"the chunk at byte {at}: CRC mismatch")
        check(crc != 0, f"the chunk at byte {at} has no CRC")
        found = {}
        times = []
        for off, op, b in records(plain, 0, len(plain), f"chunk at byte {at}"):
            check(op in CHUNK_RECORDS, f"the chunk at byte {at} holds a record of opcode {op:#x}")
            if op == MESSAGE:
                m = self.message(b)
                found.setdefault(m["channel_id"], []).append((m["log_time"], off))
                times.append(m["log_time"])
            else:
                self.define(op, b)
        check((start, end) == ((min(times), max(times)) if times else (0, 0)),
              f"the chunk at byte {at}: start/end times do not match its messages")
        return found, compression, len(data), size, start, end

    def read(self):
        d = self.d
        check(len(d) >= 2 * len(MAGIC) and d[:8] == MAGIC, "no MCAP magic at the start")
        check(d[-8:] == MAGIC, "no MCAP magic at the end (truncated)")
        end = len(d) - 8
        recs = list(records(d, 8, end, "file"))
        check(recs and recs[0][1] == HEADER, "the first record is not a Header")
        f = Fields(recs[0][2], "Header")
        self.profile, self.library = f.string(), f.string()
        check(recs[-1][1] == FOOTER, "the last record is not a Footer")
        data_end = [i for i, r in enumerate(recs) if r[1] == DATA_END]
        check(len(data_end) == 1, f"{len(data_end)} Data End records, not one")
        de = data_end[0]
        pending = None  # the chunk whose message indexes follow
        for at, op, body in recs[1:de]:
            check(op in DATA_RECORDS, f"byte {at}: opcode {op:#x} in the data section")
            if op == CHUNK:
                found, compression, clen, usize, start, cend = self.chunk(at, body)
                pending = {"offset": at, "length": 9 + len(body), "found": found, "indexes": {},
                           "compression": compression, "compressed": clen, "uncompressed": usize,
                           "start": start, "end": cend}
                self.chunks.append(pending)
            elif op == MESSAGE_INDEX:
                check(pending is not None, f"byte {at}: a Message Index before any chunk")
                f = Fields(body, "Message Index")
                channel = f.u16()
                entries = f.pairs(Fields.u64, Fields.u64)
                check(entries == pending["found"].get(channel), f"byte {at}: the message index of channel "
                      f"{channel} does not list that channel's messages in the chunk")
                pending["indexes"][channel] = at
            elif op in (SCHEMA, CHANNEL):
                self.define(op, body)
            elif op == MESSAGE:
                self.message(body)
        for c in self.chunks:
            check(set(c["indexes"]) == set(c["found"]),
                  f"the chunk at byte {c['offset']} lacks message indexes for some of its channels")
        de_at, _, de_body = recs[de]
        crc = Fields(de_body, "Data End").u32()
        check(crc == 0 or crc == zlib.crc32(d[:de_at]), "data section CRC mismatch")
        check(crc != 0, "Data End has no CRC")
        self.data_crc = crc
        # Summary, summary offsets, footer.
        ft_at, _, ft = recs[-1]
        f = Fields(ft, "Footer")
        summary_start, summary_offset_start, summary_crc = f.u64(), f.u64(), f.u32()
        after_de = de_at + 9 + len(de_body)
        check(summary_start == after_de, f"footer: summary_start {summary_start}, the summary starts at {after_de}")
        check(summary_crc != 0 and summary_crc == zlib.crc32(d[summary_start:ft_at + 1 + 8 + 16]),
              "footer: summary CRC mismatch")
        check(summary_start < summary_offset_start <= ft_at, "footer: summary offset start outside the summary")
        summary = [r for r in recs[de + 1:-1] if r[0] < summary_offset_start]
        offsets = [r for r in recs[de + 1:-1] if r[0] >= summary_offset_start]
        check(summary and summary[-1][0] + 9 + len(summary[-1][2]) == summary_offset_start,
              "footer: the summary offset section does not start at a record boundary")
        groups = {}
        last = None
        for at, op, body in summary:
            check(op in SUMMARY_RECORDS, f"byte {at}: opcode {op:#x} in the summary section")
            check(op == last or op not in groups, f"byte {at}: summary records of opcode {op:#x} not grouped")
            g = groups.setdefault(op, [at, 0])
            g[1] = at + 9 + len(body) - g[0]
            last = op
        seen = {}
        for at, op, body in offsets:
            check(op == SUMMARY_OFFSET, f"byte {at}: opcode {op:#x} in the summary offset section")
            f = Fields(body, "Summary Offset")
            op, start, length = f.u8(), f.u64(), f.u64()
            seen[op] = [start, length]
        check(seen == groups, f"summary offsets {seen} do not match the summary's groups {groups}")
        stats = [b for _, op, b in summary if op == STATISTICS]
        check(len(stats) == 1, "not one Statistics record")
        f = Fields(stats[0], "Statistics")
        st = {"message_count": f.u64(), "schema_count": f.u16(), "channel_count": f.u32(),
              "attachment_count": f.u32(), "metadata_count": f.u32(), "chunk_count": f.u32(),
              "message_start_time": f.u64(), "message_end_time": f.u64(),
              "channel_message_counts": dict(f.pairs(Fields.u16, Fields.u64))}
        check(st["message_count"] == self.messages, f"statistics: {st['message_count']} messages, counted {self.messages}")
        check(st["schema_count"] == len(self.schemas), "statistics: schema count")
        check(st["channel_count"] == len(self.channels), "statistics: channel count")
        check(st["chunk_count"] == len(self.chunks), "statistics: chunk count")
        check(st["attachment_count"] == 0 and st["metadata_count"] == 0, "statistics: attachments or metadata")
        check(st["channel_message_counts"] == self.counts, "statistics: per-channel counts differ from the messages")
        check((st["message_start_time"], st["message_end_time"]) == (min(self.times), max(self.times)),
              "statistics: start/end times")
        self.statistics = st
        summary_channels = {parse_channel(b)["id"]: parse_channel(b) for _, op, b in summary if op == CHANNEL}
        summary_schemas = {parse_schema(b)["id"]: parse_schema(b) for _, op, b in summary if op == SCHEMA}
        check(summary_channels == self.channels, "the summary's channels differ from the data section's")
        check(summary_schemas == self.schemas, "the summary's schemas differ from the data section's")
        indexes = [b for _, op, b in summary if op == CHUNK_INDEX]
        check(len(indexes) == len(self.chunks), "not one Chunk Index per chunk")
        for b, c in zip(indexes, self.chunks):
            f = Fields(b, "Chunk Index")
            ci = (f.u64(), f.u64(), f.u64(), f.u64(), dict(f.pairs(Fields.u16, Fields.u64)), f.u64(), f.string(),
                  f.u64(), f.u64())
            ilen = sum(9 + len(self.record_at(o)) for o in c["indexes"].values())
            want = (c["start"], c["end"], c["offset"], c["length"], c["indexes"], ilen, c["compression"],
                    c["compressed"], c["uncompressed"])
            check(ci == want, f"the chunk index of the chunk at byte {c['offset']} does not match it")

    def record_at(self, at):
        return self.d[at + 9:at + 9 + struct.unpack_from("<Q", self.d, at + 1)[0]]


def main(argv):
    args = list(argv[1:])
    ticks_csv = json_out = None
    if "--ticks" in args:
        i = args.index("--ticks")
        ticks_csv = args[i + 1]
        del args[i:i + 2]
    if "--json" in args:
        i = args.index("--json")
        json_out = args[i + 1]
        del args[i:i + 2]
    if len(args) != 1 or args[0].startswith("-"):
        print(__doc__, file=sys.stderr)
        return 2
    try:
        m = Mcap(args[0])
    except Exception as e:  # the first problem, whatever raised it
        print(f"mcap_reader: {args[0]}: INVALID: {e}", file=sys.stderr)
        return 1
    st = m.statistics
    print(f"{args[0]}: valid MCAP (library {m.library!r}), {st['message_count']} messages, "
          f"{len(m.channels)} channels, {len(m.schemas)} schemas, {len(m.chunks)} chunks "
          f"({', '.join(sorted({c['compression'] or 'none' for c in m.chunks}))}), "
          f"{(st['message_end_time'] - st['message_start_time']) * 1e-9:.3f} s; all CRCs checked")
    print(f"{'id':>3}  {'topic':<22} {'schema':<24} {'messages':>9}")
    for cid in sorted(m.channels):
        c = m.channels[cid]
        print(f"{cid:>3}  {c['topic']:<22} {m.schemas[c['schema_id']]['name']:<24} {m.counts.get(cid, 0):>9}")
    if ticks_csv:
        with open(ticks_csv, "w") as fh:
            fh.write("tick,t_ns,fx,fy,fz\n")
            for t in m.ticks:
                fh.write(f"{t[0]},{t[1]},{t[2]!r},{t[3]!r},{t[4]!r}\n")
    if json_out:
        with open(json_out, "w") as fh:
            json.dump({"messages": st["message_count"], "chunks": len(m.chunks),
                       "channels": {m.channels[c]["topic"]: {"schema": m.schemas[m.channels[c]["schema_id"]]["name"],
                                                             "messages": m.counts.get(c, 0)}
                                    for c in sorted(m.channels)}}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
