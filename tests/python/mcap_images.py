"""Reads an MCAP file with the official `mcap` package and prints, as one JSON list, what a
viewer would see of its image channels (those in Foxglove's schemas; the others are skipped):
per topic, the schema's name and encoding, the channel's message encoding, how many messages,
and the first message's fields (its `data` decoded from base64 and described by length and
first bytes)."""

import base64
import json
import sys

from mcap.reader import make_reader


def main(path):
    topics = {}
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        for schema, channel, message in reader.iter_messages():
            if schema is None or not schema.name.startswith("foxglove."):
                continue  # not an image channel
            entry = topics.setdefault(
                channel.topic + " " + (schema.name if schema else ""),
                {
                    "topic": channel.topic,
                    "schema": schema.name if schema else None,
                    "schema_encoding": schema.encoding if schema else None,
                    "schema_title": json.loads(schema.data).get("title") if schema else None,
                    "message_encoding": channel.message_encoding,
                    "metadata": dict(channel.metadata),
                    "count": 0,
                },
            )
            entry["count"] += 1
            if entry["count"] == 1:
                fields = json.loads(message.data)
                data = base64.b64decode(fields.pop("data"))
                fields["data_len"] = len(data)
                fields["data_head"] = data[:4].hex()
                entry["first"] = fields
    print(json.dumps(sorted(topics.values(), key=lambda entry: entry["topic"])))


if __name__ == "__main__":
    main(sys.argv[1])
