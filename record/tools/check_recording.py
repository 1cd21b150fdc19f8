#!/usr/bin/env python3
"""Reads a recording with readers that are not ours, as Foxglove and Lichtblick would.

Foxglove's own Python `mcap` reader (CRCs checked, through the summary and its chunk index),
every protobuf message decoded from the descriptor set embedded in its schema
(`mcap-protobuf-support`, the way Foxglove decodes `foxglove.*` messages), and every JSON message
validated against the JSON Schema of its channel (`jsonschema`). Counts are compared with the
summary's statistics. Exits 1 on the first thing a viewer would trip on.

Not run by CI (it needs Python packages the project does not install); run it by hand:

    python3 -m venv /tmp/mcap-check
    /tmp/mcap-check/bin/pip install mcap mcap-protobuf-support jsonschema
    /tmp/mcap-check/bin/python record/tools/check_recording.py run.mcap
"""

import collections
import json
import sys

import jsonschema
from mcap.decoder import DecoderFactory as BaseFactory
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory as ProtobufFactory


class JsonFactory(BaseFactory):
    """Decodes `json` messages and validates each against its channel's JSON Schema."""

    def decoder_for(self, message_encoding, schema):
        if message_encoding != "json" or schema is None or schema.encoding != "jsonschema":
            return None
        validator = jsonschema.validators.validator_for(json.loads(schema.data))
        checker = validator(json.loads(schema.data))

        def decode(data):
            value = json.loads(data)
            checker.validate(value)
            return value

        return decode


def main(path):
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True,
                             decoder_factories=[ProtobufFactory(), JsonFactory()])
        header = reader.get_header()
        summary = reader.get_summary()
        if summary is None:
            print(f"{path}: no summary section (not finalised?)")
            return 1
        stats = summary.statistics
        counts = collections.Counter()
        kinds = {}
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            counts[channel.topic] += 1
            kinds[channel.topic] = (schema.name if schema else "-", channel.message_encoding)
            if decoded is None:
                print(f"{channel.topic}: message {counts[channel.topic]} decoded to nothing")
                return 1
        metadata = list(reader.iter_metadata())
    total = sum(counts.values())
    print(f"{path}: library {header.library!r}, profile {header.profile!r}, "
          f"{len(summary.chunk_indexes)} chunks, {stats.channel_count} channels, "
          f"{stats.schema_count} schemas, {len(metadata)} metadata records")
    for topic in sorted(counts):
        name, encoding = kinds[topic]
        print(f"  {topic:<28} {name:<36} {encoding:<9} {counts[topic]:>9}")
    by_id = {c.id: c.topic for c in summary.channels.values()}
    summed = collections.Counter({by_id[k]: v for k, v in stats.channel_message_counts.items()})
    if total != stats.message_count or summed != counts:
        print(f"counts differ from the summary: read {total}, summary {stats.message_count}")
        return 1
    print(f"{total} messages decoded and checked, CRCs valid, counts match the summary")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print("usage: check_recording.py FILE.mcap", file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
