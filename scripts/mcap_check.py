#!/usr/bin/env python3
"""Describe an MCAP file as the reference Python reader (`mcap` package) sees it, as JSON.

The Rust tests of `node::bag` run this on bags written by `node::bag::BagWriter` to show that
another implementation reads the same channels, messages and payloads.

Prints one JSON object on stdout:

* `profile`, `library`: from the header record;
* `channels`: one entry per channel in the summary, sorted by topic: `topic`,
  `message_encoding`, `metadata`, `schema_name`, `schema_encoding`, `schema_text`, and
  `message_count`, `first_log_time` / `last_log_time` (nanoseconds, null without messages)
  counted from the messages read;
* `messages`: every message in log-time order: `topic`, `log_time`, `publish_time`,
  `sequence` and the `sha256` of its payload;
* `statistics_message_count`: the count in the statistics record (null without one).

Chunk CRCs are validated while reading. Needs `pip install -r scripts/requirements.txt`.

Usage: `python3 scripts/mcap_check.py FILE.mcap`
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


def describe(stream):
    """The JSON-ready description of the MCAP file open in binary `stream`."""
    reader = make_reader(stream, validate_crcs=True)
    header = reader.get_header()
    summary = reader.get_summary()
    channels = summary.channels if summary else {}
    schemas = summary.schemas if summary else {}

    counts = {channel_id: 0 for channel_id in channels}
    first = {}
    last = {}
    messages = []
    for _schema, channel, message in reader.iter_messages(log_time_order=True):
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
                "schema_name": schema.name if schema else None,
                "schema_encoding": schema.encoding if schema else None,
                "schema_text": schema.data.decode("utf-8", "replace") if schema else None,
                "message_count": counts.get(channel_id, 0),
                "first_log_time": first.get(channel_id),
                "last_log_time": last.get(channel_id),
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
    if len(argv) != 2:
        sys.exit(f"usage: {argv[0]} FILE.mcap")
    with open(argv[1], "rb") as stream:
        json.dump(describe(stream), sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main(sys.argv)
