#!/usr/bin/env python3
"""Describe an MCAP file as the reference Python reader (`mcap` package) sees it, as JSON.

The Rust tests of `node::bag` run this on bags written by `node::bag::BagWriter` to show that
another implementation reads the same channels, messages and payloads.

Prints one JSON object on stdout:

* `profile`, `library`: from the header record;
* `channels`: one entry per channel in the summary, sorted by topic: `topic`,
  `message_encoding`, `metadata`, `offered_qos` (the `offered_qos_profiles` metadata parsed
  as YAML, as rosbag2 reads it; null when absent or empty), `schema_name`,
  `schema_encoding`, `schema_text`, and
  `message_count`, `first_log_time` / `last_log_time` (nanoseconds, null without messages)
  counted from the messages read;
* `messages`: every message in log-time order: `topic`, `log_time`, `publish_time`,
  `sequence` and the `sha256` of its payload;
* `statistics_message_count`: the count in the statistics record (null without one).

With `--decode`, every channel with a `ros2msg` schema also gets `decoded` (how many of its
messages rosbags deserialized from CDR) and `decode_error` (the first failure, or null). Each
channel's types come only from its own schema text, registered in an empty rosbags typestore,
so this shows that the schema is a complete definition, as ROS 2 tools need it.

Chunk CRCs are validated while reading. Needs `pip install -r scripts/requirements.txt`.

Usage: `python3 scripts/mcap_check.py [--decode] FILE.mcap`
"""

import hashlib
import json
import sys

try:
    from mcap.reader import make_reader
except ImportError:
    sys.exit(
        "mcap_check.py: the Python `mcap` package is not installed; "
        "run `pip install -r scripts/requirements.txt`"
    )


class SchemaDecoder:
    """Deserializes each channel's CDR messages with rosbags, using only that channel's
    `ros2msg` schema for the types."""

    def __init__(self):
        self.stores = {}
        self.decoded = {}
        self.errors = {}

    def decode(self, schema, channel, data):
        """Deserializes one message of `channel`, counting it or keeping the first error."""
        if schema is None or schema.encoding != "ros2msg" or channel.id in self.errors:
            return
        try:
            from rosbags.typesys import Stores, get_types_from_msg, get_typestore

            store = self.stores.get(channel.id)
            if store is None:
                store = get_typestore(Stores.EMPTY)
                store.register(get_types_from_msg(schema.data.decode("utf-8"), schema.name))
                self.stores[channel.id] = store
            store.deserialize_cdr(data, schema.name)
            self.decoded[channel.id] = self.decoded.get(channel.id, 0) + 1
        except Exception as error:  # any failure is reported, not raised
            self.errors[channel.id] = f"{type(error).__name__}: {error}"

    def fields(self, channel_id):
        """The `decoded` and `decode_error` entries of a channel."""
        return {
            "decoded": self.decoded.get(channel_id, 0),
            "decode_error": self.errors.get(channel_id),
        }


def parse_qos(metadata):
    """The `offered_qos_profiles` YAML of a channel's metadata as plain values (None when
    absent or empty), read with ruamel.yaml (installed with rosbags)."""
    text = metadata.get("offered_qos_profiles", "")
    if not text:
        return None
    from ruamel.yaml import YAML

    return YAML(typ="safe").load(text)


def describe(stream, decoder=None):
    """The JSON-ready description of the MCAP file open in binary `stream`; with a
    `SchemaDecoder`, every message is also deserialized."""
    reader = make_reader(stream, validate_crcs=True)
    header = reader.get_header()
    summary = reader.get_summary()
    channels = summary.channels if summary else {}
    schemas = summary.schemas if summary else {}

    counts = {channel_id: 0 for channel_id in channels}
    first = {}
    last = {}
    messages = []
    for schema, channel, message in reader.iter_messages(log_time_order=True):
        if decoder is not None:
            decoder.decode(schema, channel, message.data)
        counts[channel.id] = counts.get(channel.id, 0) + 1
        first.setdefault(channel.id, message.log_time)
        last[channel.id] = message.log_time
        messages.append(
            {
                "topic": channel.topic,
                "log_time": message.log_time,
                "publish_time": message.publish_time,
                "sequence": message.sequence,
                "sha256": hashlib.sha256(message.data).hexdigest(),
            }
        )

    described = []
    for channel_id, channel in channels.items():
        schema = schemas.get(channel.schema_id)
        described.append(
            {
                "topic": channel.topic,
                "message_encoding": channel.message_encoding,
                "metadata": channel.metadata,
                "offered_qos": parse_qos(channel.metadata),
                "schema_name": schema.name if schema else None,
                "schema_encoding": schema.encoding if schema else None,
                "schema_text": schema.data.decode("utf-8", "replace") if schema else None,
                "message_count": counts.get(channel_id, 0),
                "first_log_time": first.get(channel_id),
                "last_log_time": last.get(channel_id),
                **(decoder.fields(channel_id) if decoder is not None else {}),
            }
        )
    described.sort(key=lambda c: c["topic"])
    statistics = summary.statistics if summary else None
    return {
        "profile": header.profile,
        "library": header.library,
        "channels": described,
        "messages": messages,
        "statistics_message_count": statistics.message_count if statistics else None,
    }


def main(argv):
    args = argv[1:]
    decoder = None
    if args[:1] == ["--decode"]:
        decoder = SchemaDecoder()
        args = args[1:]
    if len(args) != 1:
        sys.exit(f"usage: {argv[0]} [--decode] FILE.mcap")
    with open(args[0], "rb") as stream:
        json.dump(describe(stream, decoder), sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main(sys.argv)
