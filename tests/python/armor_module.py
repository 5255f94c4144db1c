#!/usr/bin/env python3
"""An ArMoR module in Python, written from docs/protocol.md alone.

Type `pyecho`: republishes on its output `output` every Counter that arrives on its input
`input`, and draws the latest on `markers` (a point and a text, section 3's `Markers`). It is a
behaviour (section 4.2): it applies once it has received a value, and says so. It speaks the whole contract a module needs: the environment and `--describe`
(sections 1 and 5), framing (2), the Noise handshake and encrypted records when the run has a
secret (2.5), the agent (4.1), the config server (4.2), and both sides of a data link (4.3).

Standard library, plus `noiseprotocol` (module `noise`) and `cryptography`.

Threads only read: one per connection, each turning what it reads into an event on one queue.
The main loop takes the events one by one and does all the work, writes included, so that a
stuck main loop stops answering `ping` and is restarted, as section 4.2 asks.
"""

import json
import os
import queue
import socket
import struct
import sys
import threading
import time

DESCRIPTION = """\
<?xml version="1.0" encoding="UTF-8"?>
<module type="pyecho" version="0.1.0" controllable="true">
  <doc>Republishes every Counter it receives (a module in Python, from docs/protocol.md).</doc>
  <input name="input" type="Counter" doc="the values to republish"/>
  <output name="output" type="Counter" doc="the same values, in the order they came"/>
  <output name="markers" type="Markers" doc="the latest value, drawn at (value, 0) in the world"/>
</module>
"""

# Section 2: the hello, frame kinds and limits.
HELLO = b"ARMR" + struct.pack("<H", 1)
MAX_FRAME = 64 * 1024 * 1024
CONTROL, DATA, NOISE_1, NOISE_2, NOISE_CONFIRM = 1, 2, 3, 4, 5
MAX_HANDSHAKE_FRAME = 305  # bytes after the kind
HELLO_TIMEOUT = 5.0

# Section 2.5: the Noise protocol, the prologue and the records.
NOISE_NAME = b"Noise_NNpsk0_25519_AESGCM_SHA256"
PROLOGUE = b"ARMOR/1 "
MAX_RECORD_PLAINTEXT = 65535 - 16

INPUT, DATA_TYPE = "input", "Counter"
# Each output and its data type.
OUTPUTS = {"output": "Counter", "markers": "Markers"}


def log(level, text):
    print(f"{time.strftime('%H:%M:%S')} {level} pyecho: {text}", file=sys.stderr, flush=True)


# ---------------------------------------------------------------------------------------------
# Keys (section 2.5): HKDF-SHA256. armor run hands a module K(its name) over the descriptor
# named by ARMOR_KEY_FD (section 1); the link key of a dialer `d` at this module's data port is
# HKDF-Expand(K(self), "link:" + d, 32).


def make_non_dumpable():
    """Section 1: first thing, before the key is read, so that a process of the same user can
    read neither this one's memory nor its descriptors (prctl(PR_SET_DUMPABLE, 0))."""
    import ctypes

    PR_SET_DUMPABLE = 4
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(PR_SET_DUMPABLE, 0, 0, 0, 0) != 0:
        log("WARN", f"cannot make this process non-dumpable: errno {ctypes.get_errno()}")


def take_key(env):
    """Section 1: the key behind ARMOR_KEY_FD (64 hex digits, then end of file); the descriptor
    is read to its end and closed (its number then stands for /dev/null)."""
    fd = env.get("ARMOR_KEY_FD")
    if not fd:
        return None
    fd = int(fd)
    text = b""
    while True:
        chunk = os.read(fd, 1024)
        if not chunk:
            break
        text += chunk
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, fd)  # closes the pipe
    os.close(null)
    return bytes.fromhex(text.decode().strip())


def hkdf_expand(prk, info):
    from cryptography.hazmat.primitives import hashes
    from cryptography.hazmat.primitives.kdf.hkdf import HKDFExpand

    return HKDFExpand(hashes.SHA256(), 32, info).derive(prk)


def link_key(own_key, dialer):
    return hkdf_expand(own_key, b"link:" + dialer)


def module_key(secret_file, name):
    """K(name) from the secret file, as a tool that holds the secret derives it (a module gets
    its own over ARMOR_KEY_FD instead). HKDF-Extract is HMAC(salt, IKM) (RFC 5869)."""
    import hashlib
    import hmac

    with open(secret_file, "rb") as file:
        secret = file.read().rstrip(b"\r\n")
    prk = hmac.new(b"ARMOR/1 secret", secret, hashlib.sha256).digest()
    return hkdf_expand(prk, b"module:" + name.encode())


# ---------------------------------------------------------------------------------------------
# Encoding (section 3): postcard's varint for Counter, and data samples (section 2.4).


def encode_varint(value):
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def encode_markers(value):
    """Markers (section 3): a sequence of Marker, each shape and frame as varint indices, rgba
    as four bytes, size_px as f32, points as a sequence of (f32, f32), then a string."""
    def marker(shape, rgba, points, text):
        out = encode_varint(shape) + encode_varint(0)  # frame 0: the world
        out += bytes(rgba) + struct.pack("<f", 4.0)
        out += encode_varint(len(points)) + b"".join(struct.pack("<ff", x, y) for x, y in points)
        text = text.encode()
        return out + encode_varint(len(text)) + text

    point = (float(value), 0.0)
    markers = [marker(0, (200, 40, 160, 255), [point], "value"),
               marker(4, (200, 40, 160, 255), [point], f"pyecho {value}")]
    return encode_varint(len(markers)) + b"".join(markers)


def decode_varint(data):
    value, shift = 0, 0
    for index, byte in enumerate(data):
        value |= (byte & 0x7F) << shift
        if not byte & 0x80:
            if index + 1 != len(data) or value >= 1 << 64:
                raise ValueError("not one u64 varint")
            return value
        shift += 7
    raise ValueError("truncated varint")


class Closed(Exception):
    """The peer closed the connection, or broke the protocol: close it."""


def recv_exact(sock, count):
    data = bytearray()
    while len(data) < count:
        chunk = sock.recv(count - len(data))
        if not chunk:
            raise Closed("connection closed")
        data += chunk
    return bytes(data)


def frame_bytes(kind, payload):
    return struct.pack("<IB", len(payload) + 1, kind) + payload


def read_plain_frame(sock, max_body=MAX_FRAME - 1):
    """One frame read byte-exactly from the socket (for the handshake: what follows it may be
    records, which must stay in the socket)."""
    (length,) = struct.unpack("<I", recv_exact(sock, 4))
    if length < 1 or length - 1 > max_body:
        raise Closed(f"frame of {length} bytes")
    body = recv_exact(sock, length)
    return body[0], body[1:]


# ---------------------------------------------------------------------------------------------
# A connection after the hello and the handshake: frames in both directions, in clear or in
# records (a u16 length, then a Noise transport message).


class Link:
    def __init__(self, sock, noise=None, encrypted=False, peer=""):
        self.sock = sock
        self.noise = noise if encrypted else None
        self.authenticated = noise is not None
        self.peer = peer
        self.inbuf = bytearray()
        self.send_lock = threading.Lock()

    def send(self, kind, payload):
        data = frame_bytes(kind, payload)
        if self.noise is not None:
            records = bytearray()
            for start in range(0, len(data), MAX_RECORD_PLAINTEXT):
                sealed = self.noise.encrypt(data[start : start + MAX_RECORD_PLAINTEXT])
                records += struct.pack("<H", len(sealed)) + sealed
            data = bytes(records)
        with self.send_lock:
            self.sock.sendall(data)

    def send_message(self, message):
        self.send(CONTROL, json.dumps(message).encode())

    def _fill(self):
        if self.noise is not None:
            (length,) = struct.unpack("<H", recv_exact(self.sock, 2))
            try:
                self.inbuf += self.noise.decrypt(recv_exact(self.sock, length))
            except Exception as err:  # a record that does not decrypt
                raise Closed(f"bad record: {err}") from err
        else:
            chunk = self.sock.recv(65536)
            if not chunk:
                raise Closed("connection closed")
            self.inbuf += chunk

    def read_frame(self):
        while len(self.inbuf) < 5:
            self._fill()
        (length,) = struct.unpack_from("<I", self.inbuf)
        if length < 1 or length > MAX_FRAME:
            raise Closed(f"frame of {length} bytes")
        kind = self.inbuf[4]
        if kind not in (CONTROL, DATA):
            raise Closed(f"frame of kind {kind}")
        while len(self.inbuf) < 4 + length:
            self._fill()
        payload = bytes(self.inbuf[5 : 4 + length])
        del self.inbuf[: 4 + length]
        return kind, payload

    def read_message(self):
        kind, payload = self.read_frame()
        if kind != CONTROL:
            raise Closed("a data frame where a control message was due")
        message = json.loads(payload)
        if not isinstance(message, dict) or "type" not in message:
            raise Closed("a control message without type")
        return message

    def close(self):
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.sock.close()


def new_noise(psk, identity, initiator):
    from noise.connection import NoiseConnection

    noise = NoiseConnection.from_name(NOISE_NAME)
    if initiator:
        noise.set_as_initiator()
    else:
        noise.set_as_responder()
    noise.set_psks(psk=psk)
    noise.set_prologue(PROLOGUE + bytes([len(identity)]) + identity)
    noise.start_handshake()
    return noise


def dial(addr, identity=None, psk=None, encrypt=False):
    """Connects to `host:port`: the hello, then, with a key, the handshake as the initiator."""
    host, port = addr.rsplit(":", 1)
    sock = socket.create_connection((host.strip("[]"), int(port)), timeout=HELLO_TIMEOUT)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    try:
        sock.sendall(HELLO)
        if psk is None:
            if recv_exact(sock, 6) != HELLO:
                raise Closed("wrong hello")
            sock.settimeout(None)
            return Link(sock, peer=addr)
        name = identity.encode()
        noise = new_noise(psk, name, initiator=True)
        message_1 = noise.write_message(bytes([1 if encrypt else 0]))
        sock.sendall(frame_bytes(NOISE_1, bytes([len(name)]) + name + bytes(message_1)))
        if recv_exact(sock, 6) != HELLO:
            raise Closed("wrong hello")
        kind, body = read_plain_frame(sock, MAX_HANDSHAKE_FRAME)
        if kind != NOISE_2:
            raise Closed(f"frame of kind {kind} instead of the handshake's second message")
        flags = noise.read_message(body)
        encrypted = bool(flags and flags[0] & 1)
        sock.sendall(frame_bytes(NOISE_CONFIRM, noise.encrypt(b"")))
        sock.settimeout(None)
        return Link(sock, noise, encrypted, peer=addr)
    except BaseException:
        sock.close()
        raise


def accept(sock, own_key, insist_on_encryption):
    """The listener's side: the hello, then, with a key, the handshake as the responder with the
    link key for the identity the dialer claims. Returns the link and that identity (or None)."""
    sock.settimeout(HELLO_TIMEOUT)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    # With a key, not a byte before a valid message 1: the hello goes with message 2.
    if own_key is None:
        sock.sendall(HELLO)
    if recv_exact(sock, 6) != HELLO:
        raise Closed("wrong hello")
    if own_key is None:
        sock.settimeout(None)
        return Link(sock), None
    kind, body = read_plain_frame(sock, MAX_HANDSHAKE_FRAME)
    if kind != NOISE_1 or not body or len(body) < 1 + body[0] or body[0] == 0:
        raise Closed("no handshake")
    identity = body[1 : 1 + body[0]]
    noise = new_noise(link_key(own_key, identity), identity, initiator=False)
    try:
        flags = noise.read_message(body[1 + body[0] :])
    except Exception as err:
        raise Closed(f"wrong key for {identity!r}: {err}") from err
    encrypted = bool(flags and flags[0] & 1) or insist_on_encryption
    sock.sendall(HELLO + frame_bytes(NOISE_2, bytes(noise.write_message(bytes([int(encrypted)])))))
    kind, body = read_plain_frame(sock, MAX_HANDSHAKE_FRAME)
    try:
        if kind != NOISE_CONFIRM or noise.decrypt(body) != b"":
            raise Closed("no confirmation")
    except Closed:
        raise
    except Exception as err:
        raise Closed(f"wrong confirmation: {err}") from err
    sock.settimeout(None)
    return Link(sock, noise, encrypted), identity.decode()


def describe_link(link):
    if link.noise is not None:
        return " (authenticated, encrypted)"
    return " (authenticated)" if link.authenticated else ""


# ---------------------------------------------------------------------------------------------
# The module.


class Subscriber:
    def __init__(self, link, message):
        self.link = link
        self.data_name = message.get("data_name")
        self.pull = bool(message.get("pull", False))
        rate = message.get("max_rate_hz")
        self.min_gap = 1.0 / rate if rate and not message.get("reliable") else 0.0
        self.last_sent = 0.0
        self.pulls_waiting = 0


class Module:
    def __init__(self):
        env = os.environ
        self.name = env["ARMOR_MODULE"]
        self.supervisor_addr = env["ARMOR_SUPERVISOR"]
        self.agent_addr = env["ARMOR_AGENT"]
        self.epoch_ns = int(env.get("ARMOR_EPOCH_NS", time.time_ns()))
        self.time_scale = float(env.get("ARMOR_TIME_SCALE", "1"))
        self.key = take_key(env)
        self.encrypt = env.get("ARMOR_ENCRYPT") == "1"
        self.events = queue.Queue()
        self.supervisor = None
        self.timers = []  # (deadline, action)
        self.active = True
        self.listener = None
        self.data_addr = None
        self.output_names = {}  # output → its data name
        self.agent = None
        self.source = None  # the data name feeding the input
        self.input_link = None
        self.input_state = "unlinked"  # unlinked, looking, dialing, linked
        self.input_generation = 0
        self.subscribers = []
        self.seq = {}  # data name → the last sequence number sent
        self.latest = {}  # data name → the last sample
        self.applicable = None
        self.stats = {"cycles": 0, "busy_us": 0, "sent": {}, "received": 0}

    # --- plumbing --------------------------------------------------------------------------

    def spawn(self, target, *args):
        threading.Thread(target=target, args=args, daemon=True).start()

    def reader(self, link, tag, *extra):
        """Reads control messages from `link` until it closes; each is an event."""
        try:
            while True:
                self.events.put((tag, link, *extra, link.read_message()))
        except (Closed, OSError, ValueError) as err:
            self.events.put((tag + "_closed", link, *extra, str(err)))

    def later(self, seconds, action):
        self.timers.append((time.monotonic() + seconds, action))

    def connect(self, tag, addr, first_message):
        """In a thread: dial the config server or the agent (with the module's own key; both
        always encrypt), send `first_message`, then read; the main loop hears `TAG_up`, then
        `TAG` for each message and `TAG_closed`, or `TAG_down` if the connection failed."""
        try:
            link = dial(addr, self.name, self.key, self.encrypt)
            if first_message is not None:
                link.send_message(first_message)
        except (Closed, OSError, ValueError) as err:
            self.events.put((tag + "_down", str(err)))
            return
        self.events.put((tag + "_up", link))
        self.reader(link, tag)

    def run_time_ns(self):
        return int((time.time_ns() - self.epoch_ns) * self.time_scale)

    # --- the main loop ---------------------------------------------------------------------

    def run(self):
        self.connect_supervisor()
        self.connect_agent()
        while True:
            now = time.monotonic()
            due = [timer for timer in self.timers if timer[0] <= now]
            self.timers = [timer for timer in self.timers if timer[0] > now]
            for _, action in due:
                action()
            timeout = min((deadline for deadline, _ in self.timers), default=now + 1.0) - now
            try:
                event = self.events.get(timeout=max(timeout, 0.0))
            except queue.Empty:
                continue
            started = time.monotonic()
            self.stats["cycles"] += 1
            getattr(self, "on_" + event[0])(*event[1:])
            self.stats["busy_us"] += int((time.monotonic() - started) * 1e6)

    # --- config server (section 4.2) -------------------------------------------------------

    def connect_supervisor(self):
        hello = {"type": "hello", "module": self.name, "pid": os.getpid()}
        self.spawn(self.connect, "supervisor", self.supervisor_addr, hello)

    def on_supervisor_up(self, link):
        self.supervisor = link

    def on_supervisor_down(self, reason):
        log("WARN", f"no config server at {self.supervisor_addr} ({reason}); again in 250 ms")
        self.later(0.25, self.connect_supervisor)

    def send_to_supervisor(self, message):
        if self.supervisor is not None:
            try:
                self.supervisor.send_message(message)
            except OSError:
                pass  # its reader reports the close

    def on_supervisor(self, _link, message):
        kind = message["type"]
        if kind == "config":
            self.apply(message)
            self.send_to_supervisor({"type": "ready"})
        elif kind == "ping":
            self.send_to_supervisor(
                {
                    "type": "pong",
                    "stats": {
                        "cycles": self.stats["cycles"],
                        "busy_us": self.stats["busy_us"],
                        "sent": dict(self.stats["sent"]),
                        "received": {INPUT: self.stats["received"]},
                        **({} if self.applicable is None else {"applicable": self.applicable}),
                    },
                }
            )
        elif kind == "stop":
            self.active = False
        elif kind == "start":
            self.active = True
        elif kind == "shutdown":
            log("INFO", "shutdown")
            sys.exit(0)
        elif kind == "error":
            log("ERROR", f"config server: {message.get('message')}")
            sys.exit(1)

    def on_supervisor_closed(self, link, reason):
        # Section 4.2: reconnect and say hello again (armor run kills its modules when it dies).
        if link is self.supervisor:
            log("WARN", f"lost the config server ({reason}); reconnecting")
            self.supervisor = None
            self.later(0.25, self.connect_supervisor)

    def apply(self, config):
        self.active = config.get("active", True)
        if self.listener is None:
            self.listener = socket.create_server((config.get("host", "127.0.0.1"), 0))
            host, port = self.listener.getsockname()[:2]
            self.data_addr = f"{host}:{port}"
            self.spawn(self.accept_loop)
            log("INFO", f"accepting subscribers on {self.data_addr}")
        output_names = {port: config["outputs"][port] for port in OUTPUTS if port in config["outputs"]}
        if output_names != self.output_names:
            self.output_names = output_names
            self.register()
        source = config["inputs"].get(INPUT)
        if source != self.source:
            self.relink(source)

    # --- agent (section 4.1) ---------------------------------------------------------------

    def connect_agent(self):
        self.spawn(self.connect, "agent", self.agent_addr, None)

    def on_agent_up(self, link):
        self.agent = link
        self.register()
        if self.input_state == "looking":
            self.lookup()

    def on_agent_down(self, reason):
        log("WARN", f"no agent at {self.agent_addr} ({reason}); again in 250 ms")
        self.later(0.25, self.connect_agent)

    def on_agent_closed(self, link, reason):
        if link is self.agent:
            log("WARN", f"the agent went away ({reason}); reconnecting")
            self.agent = None
            self.later(0.25, self.connect_agent)

    def send_to_agent(self, message):
        if self.agent is not None:
            try:
                self.agent.send_message(message)
            except OSError:
                pass  # its reader reports the close

    def register(self):
        if self.output_names and self.data_addr:
            adverts = [
                {"data_name": name, "data_type": OUTPUTS[port], "addr": self.data_addr}
                for port, name in self.output_names.items()
            ]
            self.send_to_agent({"type": "register", "module": self.name, "outputs": adverts})

    def lookup(self):
        if self.input_state == "looking" and self.source:
            self.send_to_agent({"type": "lookup", "data_name": self.source})

    def on_agent(self, link, message):
        kind = message["type"]
        if kind == "registered":
            log("INFO", f"registered {', '.join(self.output_names.values())} at {self.data_addr}")
        elif kind == "error":
            log("ERROR", f"agent: {message.get('message')}")
        elif kind == "unknown" and message.get("data_name") == self.source:
            self.later(0.2, self.lookup)
        elif kind == "provider" and message.get("data_name") == self.source:
            if self.input_state == "looking":
                self.input_state = "dialing"
                key = bytes.fromhex(message["key"]) if message.get("key") else None
                self.spawn(self.subscribe_input, self.input_generation, self.source, message["addr"], key)

    # --- our input: subscriber side of section 4.3 -----------------------------------------

    def relink(self, source):
        self.input_generation += 1
        if self.input_link is not None:
            self.input_link.close()
            self.input_link = None
        self.source = source
        self.input_state = "looking" if source else "unlinked"
        self.lookup()

    def subscribe_input(self, generation, source, addr, key):
        """In a thread: dial the provider, subscribe, and turn its data frames into events."""
        try:
            if self.key is not None and key is None:
                raise Closed("the agent gave no link key")
            link = dial(addr, self.name, key, self.encrypt)
            link.send_message(
                {
                    "type": "subscribe",
                    "data_name": source,
                    "data_type": DATA_TYPE,
                    "subscriber": f"{self.name}.{INPUT}",
                    "reliable": True,
                }
            )
            answer = link.read_message()
            if answer["type"] != "subscribed":
                link.close()
                raise Closed(f"refused: {answer.get('reason', answer)}")
            self.events.put(("input_linked", generation, link))
            while True:
                kind, payload = link.read_frame()
                if kind == DATA:  # seq: u64, stamp_ns: u64, then the Counter
                    if len(payload) < 17:
                        raise Closed("a data sample too short")
                    self.events.put(("sample", generation, decode_varint(payload[16:])))
        except (Closed, OSError, ValueError, KeyError) as err:
            self.events.put(("input_lost", generation, f"{addr}: {err}"))

    def on_input_linked(self, generation, link):
        if generation != self.input_generation:
            link.close()
            return
        self.input_link = link
        self.input_state = "linked"
        log("INFO", f"subscribed to {self.source} at {link.peer}{describe_link(link)}")

    def on_input_lost(self, generation, reason):
        if generation != self.input_generation:
            return
        log("WARN", f"input link lost ({reason}); looking {self.source} up again")
        self.input_link = None
        self.input_state = "looking"
        self.later(0.15, self.lookup)

    def on_sample(self, generation, value):
        if generation != self.input_generation:
            return
        self.stats["received"] += 1
        if self.stats["received"] % 10 == 0:
            log("INFO", f"republished {self.stats['received']} values, last {value}")
        if self.active:
            if self.applicable is not True:
                self.applicable = True
                self.send_to_supervisor({"type": "applicable", "applicable": True})
            self.publish("output", encode_varint(value))
            self.publish("markers", encode_markers(value))

    # --- our output: provider side of section 4.3 ------------------------------------------

    def accept_loop(self):
        while True:
            sock, peer = self.listener.accept()
            self.spawn(self.serve_subscriber, sock, peer)

    def serve_subscriber(self, sock, peer):
        """In a thread: hello and handshake, then the subscriber's messages become events."""
        try:
            link, identity = accept(sock, self.key, self.encrypt)
            link.peer = identity or f"{peer[0]}:{peer[1]}"
        except (Closed, OSError, ValueError) as err:
            log("WARN", f"refused a connection from {peer[0]}:{peer[1]}: {err}")
            sock.close()
            return
        self.reader(link, "subscriber", identity)

    def on_subscriber(self, link, identity, message):
        kind = message["type"]
        current = next((sub for sub in self.subscribers if sub.link is link), None)
        if kind == "subscribe" and current is None:
            reason = None
            data_name = message.get("data_name")
            port = next((p for p, name in self.output_names.items() if name == data_name), None)
            if port is None:
                reason = f"no output `{data_name}` here"
            elif message.get("data_type") != OUTPUTS[port]:
                reason = f"`{data_name}` carries {OUTPUTS[port]}"
            elif identity is not None and not str(message.get("subscriber", "")).startswith(
                identity + "."
            ):
                reason = f"`{message.get('subscriber')}` is not an input of `{identity}`"
            if reason:
                link.send_message({"type": "refused", "reason": reason})
                link.close()
                return
            self.subscribers.append(Subscriber(link, message))
            link.send_message({"type": "subscribed"})
            name = message.get("subscriber")
            log("INFO", f"{name} subscribed to {data_name}{describe_link(link)}")
        elif kind == "pull" and current is not None:
            if current.data_name not in self.latest:
                current.pulls_waiting += 1
            else:
                self.send_to(current, self.latest[current.data_name])
        elif kind == "unsubscribe" and current is not None:
            self.subscribers.remove(current)
            link.send_message({"type": "unsubscribed"})
            link.close()  # this connection carries no subscription of ours the other way
        else:
            link.close()  # anything else closes the connection (section 4.3)

    def on_subscriber_closed(self, link, _identity, reason):
        self.subscribers = [sub for sub in self.subscribers if sub.link is not link]

    def publish(self, port, encoded):
        """Sends one sample of output `port` (its encoding given) to its subscribers."""
        data_name = self.output_names.get(port)
        if data_name is None:
            return
        self.seq[data_name] = self.seq.get(data_name, 0) + 1
        sample = struct.pack("<QQ", self.seq[data_name], self.run_time_ns()) + encoded
        self.latest[data_name] = sample
        self.stats["sent"][data_name] = self.stats["sent"].get(data_name, 0) + 1
        now = time.monotonic()
        for sub in [sub for sub in self.subscribers if sub.data_name == data_name]:
            if sub.pull:
                if sub.pulls_waiting:
                    sub.pulls_waiting -= 1
                    self.send_to(sub, sample)
            elif now - sub.last_sent >= sub.min_gap:
                sub.last_sent = now
                self.send_to(sub, sample)

    def send_to(self, sub, payload):
        try:
            sub.link.send(DATA, payload)
        except OSError:
            self.subscribers.remove(sub)
            sub.link.close()


def main():
    if sys.argv[1:] == ["--describe"]:
        sys.stdout.write(DESCRIPTION)
        return 0
    if sys.argv[1:2] == ["--key"] and len(sys.argv) in (4, 5):
        # --key SECRET_FILE MODULE [DIALER]: K(MODULE), or the link key of DIALER at MODULE.
        key = module_key(sys.argv[2], sys.argv[3])
        if len(sys.argv) == 5:
            key = link_key(key, sys.argv[4].encode())
        print(key.hex())
        return 0
    make_non_dumpable()
    module = Module()
    log("INFO", f"started as {module.name} (secret: {module.key is not None}, "
        f"encrypt: {module.encrypt})")
    module.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
