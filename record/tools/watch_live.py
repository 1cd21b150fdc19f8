#!/usr/bin/env python3
"""A Foxglove WebSocket viewer that is not ours: subscribes to every channel of `--live` and
decodes what arrives, as Foxglove and Lichtblick would (`foxglove.websocket.v1`).

Protobuf channels are decoded with the descriptor set the server advertises, JSON channels are
validated against their JSON Schema. Prints the messages received per topic and exits 1 if any
failed to decode, or if nothing arrived. With --stall it subscribes and then never reads: the
stalled viewer whose cost the server must bear by dropping, not by slowing the run. With
--no-decode it reads and counts frames only: a viewer that costs the machine little CPU of its
own, to time the server's share.

Not run by CI (it needs Python packages the project does not install); run it by hand:

    python3 -m venv /tmp/mcap-check
    /tmp/mcap-check/bin/pip install websockets protobuf jsonschema
    cargo run --release -p demo -- --seconds 30 --live 127.0.0.1:8765 &
    /tmp/mcap-check/bin/python record/tools/watch_live.py ws://127.0.0.1:8765 --seconds 20
"""

import argparse
import asyncio
import base64
import collections
import json
import struct
import sys
import time

import jsonschema
import websockets
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory


def protobuf_class(schema_name, data):
    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(data))
    pool = descriptor_pool.DescriptorPool()
    for f in files.file:
        pool.Add(f)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))


def decoder(channel):
    if channel["encoding"] == "protobuf":
        cls = protobuf_class(channel["schemaName"], channel["schema"])
        return cls.FromString
    if channel["encoding"] == "json":
        schema = json.loads(channel["schema"])
        checker = jsonschema.validators.validator_for(schema)(schema)

        def decode(data):
            value = json.loads(data)
            checker.validate(value)
            return value

        return decode
    raise ValueError(f"channel {channel['topic']}: encoding {channel['encoding']!r}")


async def watch(url, seconds, stall, decode):
    async with websockets.connect(url, subprotocols=["foxglove.websocket.v1"],
                                  max_size=None, max_queue=None if not stall else 1) as ws:
        channels, subs, decoders = {}, {}, {}
        counts, failed = collections.Counter(), collections.Counter()
        server = None
        deadline = time.monotonic() + seconds
        next_sub = 1
        while time.monotonic() < deadline:
            try:
                frame = await asyncio.wait_for(ws.recv(), deadline - time.monotonic())
            except asyncio.TimeoutError:
                break
            if isinstance(frame, str):
                op = json.loads(frame)
                if op["op"] == "serverInfo":
                    server = op
                elif op["op"] == "advertise":
                    new = []
                    for c in op["channels"]:
                        channels[c["id"]] = c
                        decoders[c["id"]] = decoder(c)
                        subs[next_sub] = c["id"]
                        new.append({"id": next_sub, "channelId": c["id"]})
                        next_sub += 1
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))
                    if stall:
                        # Subscribed; now never read again.
                        await asyncio.sleep(max(0.0, deadline - time.monotonic()))
                        print(f"stalled for {seconds} s after subscribing to {len(new)} channels")
                        return 0
                continue
            if frame[0] != 0x01:
                continue
            sub, _ts = struct.unpack_from("<IQ", frame, 1)
            channel = subs[sub]
            topic = channels[channel]["topic"]
            try:
                if decode:
                    decoders[channel](frame[13:])
                counts[topic] += 1
            except Exception as e:  # a viewer's view of a bad message
                failed[topic] += 1
                print(f"{topic}: {e}", file=sys.stderr)
    name = server["name"] if server else "?"
    print(f"server {name!r}, {len(channels)} channels advertised, watched {seconds} s")
    for c in sorted(channels.values(), key=lambda c: c["topic"]):
        t = c["topic"]
        print(f"  {t:<28} {c['schemaName']:<36} {c['encoding']:<9} {counts[t]:>7} {failed[t]:>4} bad")
    if failed or not counts:
        return 1
    print(f"{sum(counts.values())} messages " + ("decoded and checked" if decode else "read"))
    return 0


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("url")
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--stall", action="store_true")
    p.add_argument("--no-decode", action="store_true")
    a = p.parse_args()
    sys.exit(asyncio.run(watch(a.url, a.seconds, a.stall, not a.no_decode)))


if __name__ == "__main__":
    main()
