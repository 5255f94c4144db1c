#!/usr/bin/env python3
"""Publishes camera images from Python, written from docs/protocol.md: the `Image` encoding of
section 3 (postcard: varints, length-prefixed strings, the pixels last) in data frames of
section 2.4, on an output registered at the agent (section 4.1) and served to one subscriber
(section 4.3). The framing and the hello come from armor_module.py beside it.

Usage: image_publisher.py AGENT_ADDR MODULE_NAME

Once a subscriber is linked, sends two images on MODULE_NAME.image, then waits for the
subscriber to close the connection:
- 4 x 3 rgb8, pixel (x, y) = (10 x, 20 y, 7), taken at 1.5 s, frame `py-front`;
- 640 x 480 mono8 (307,200 bytes: a large sample), pixel (x, y) = (x + y) mod 256, at 2 s.
"""

import socket
import struct
import sys
import time

from armor_module import DATA, Closed, accept, dial, encode_varint


def string(text):
    data = text.encode()
    return encode_varint(len(data)) + data


def image(width, height, encoding, stamp_ns, frame_id, pixels):
    """The postcard encoding of an Image (docs/protocol.md, section 3)."""
    return (
        encode_varint(width)
        + encode_varint(height)
        + string(encoding)
        + encode_varint(stamp_ns)
        + string(frame_id)
        + encode_varint(len(pixels))
        + pixels
    )


def main(agent_addr, name):
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    port = listener.getsockname()[1]
    data_name = name + ".image"
    agent = dial(agent_addr)
    agent.send_message(
        {
            "type": "register",
            "module": name,
            "outputs": [
                {"data_name": data_name, "data_type": "Image", "addr": f"127.0.0.1:{port}"}
            ],
        }
    )
    answer = agent.read_message()
    if answer["type"] != "registered":
        raise SystemExit(f"the agent said {answer}")
    print(f"registered {data_name}", flush=True)

    sock, _ = listener.accept()
    link, _ = accept(sock, None, False)
    subscribe = link.read_message()
    if subscribe.get("type") != "subscribe" or subscribe.get("data_name") != data_name:
        link.send_message({"type": "refused", "reason": f"no {subscribe.get('data_name')}"})
        raise SystemExit(f"unexpected {subscribe}")
    if subscribe.get("data_type") != "Image":
        link.send_message({"type": "refused", "reason": f"{data_name} carries Image"})
        raise SystemExit(f"unexpected {subscribe}")
    link.send_message({"type": "subscribed"})
    print(f"{subscribe.get('subscriber')} subscribed", flush=True)

    rgb = bytes(
        channel for y in range(3) for x in range(4) for channel in (10 * x, 20 * y, 7)
    )
    mono = bytes((x + y) % 256 for y in range(480) for x in range(640))
    samples = [
        image(4, 3, "rgb8", 1_500_000_000, "py-front", rgb),
        image(640, 480, "mono8", 2_000_000_000, "py-front", mono),
    ]
    for seq, sample in enumerate(samples, start=1):
        stamp_ns = time.monotonic_ns()
        link.send(DATA, struct.pack("<QQ", seq, stamp_ns) + sample)
    print("sent 2 images", flush=True)
    try:
        while True:
            link.read_frame()
    except (Closed, OSError):
        pass


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
