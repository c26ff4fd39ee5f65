"""Reads an MCAP file with the PyPI `mcap` package (an independent reader)
and prints one JSON object: per channel topic its schema name, schema
encoding, message encoding and message count, and whether every message is
JSON that its channel's JSON Schema's required fields are present in. Used
by tests/tests/mcap_recording.rs."""

import json
import sys

from mcap.reader import make_reader


def main(path):
    channels = {}
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            entry = channels.setdefault(
                channel.topic,
                {
                    "schema_name": schema.name if schema else None,
                    "schema_encoding": schema.encoding if schema else None,
                    "message_encoding": channel.message_encoding,
                    "messages": 0,
                    "valid_json": 0,
                    "first": None,
                },
            )
            entry["messages"] += 1
            required = json.loads(schema.data).get("required", []) if schema else []
            try:
                value = json.loads(message.data)
            except ValueError:
                continue
            if all(k in value for k in required):
                entry["valid_json"] += 1
            if entry["first"] is None:
                entry["first"] = value
        summary = reader.get_summary()
    print(json.dumps({
        "channels": channels,
        "message_count": summary.statistics.message_count if summary and summary.statistics else None,
    }))


if __name__ == "__main__":
    main(sys.argv[1])
