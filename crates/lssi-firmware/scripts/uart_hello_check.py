#!/usr/bin/env python3
"""Checks that the firmware speaks the lssi protocol on UART0: connects to QEMU's UART
socket, sends a `Hello` frame and expects the `HelloReply` of a device built with a window
capacity of 256 samples, 16 terms and batches of 24 samples.

    LSSI_SERIAL="-serial unix:/tmp/lssi-uart.sock,server=on,wait=off" cargo run --release &
    python3 scripts/uart_hello_check.py /tmp/lssi-uart.sock

A frame is a postcard message, its CRC-32C (little-endian) appended, COBS-encoded and ended
by 0x00 (crates/lssi-proto). Also takes HOST:PORT for `-serial tcp:...`. Exits 0 on the
expected reply, 1 otherwise. The full protocol is exercised by tests/tests/qemu.rs.
"""

import os
import re
import socket
import sys
import time


def protocol_version() -> int:
    """lssi-proto's PROTOCOL_VERSION, read from its source (one place to bump it)."""
    here = os.path.dirname(os.path.abspath(__file__))
    source = os.path.join(here, "..", "..", "lssi-proto", "src", "lib.rs")
    with open(source, encoding="utf-8") as f:
        found = re.search(r"pub const PROTOCOL_VERSION: u16 = (\d+);", f.read())
    if found is None or int(found.group(1)) > 127:
        sys.exit(f"hello: no one-byte PROTOCOL_VERSION in {source}")
    return int(found.group(1))


PROTOCOL_VERSION = protocol_version()
# HostMsg::Hello (variant 0) { protocol_version: varint }
HELLO = bytes([0x00, PROTOCOL_VERSION])
# DeviceMsg::HelloReply (variant 0) { version, max_terms 16, window_capacity 256
# (varint 0x80 0x02), max_batch 24 }
HELLO_REPLY = bytes([0x00, PROTOCOL_VERSION, 16, 0x80, 0x02, 24])


def crc32c(data: bytes) -> int:
    crc = 0xFFFFFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ (0x82F63B78 if crc & 1 else 0)
    return crc ^ 0xFFFFFFFF


def cobs_encode(data: bytes) -> bytes:
    out, block = bytearray(), bytearray()
    for byte in data:
        if byte == 0:
            out += bytes([len(block) + 1]) + block
            block.clear()
        else:
            block.append(byte)
            if len(block) == 254:
                out += bytes([255]) + block
                block.clear()
    return bytes(out + bytes([len(block) + 1]) + block)


def cobs_decode(data: bytes) -> bytes:
    out, i = bytearray(), 0
    while i < len(data):
        code = data[i]
        out += data[i + 1 : i + code]
        i += code
        if code < 255 and i < len(data):
            out.append(0)
    return bytes(out)


def frame(payload: bytes) -> bytes:
    return cobs_encode(payload + crc32c(payload).to_bytes(4, "little")) + b"\x00"


def connect(where: str, deadline: float) -> socket.socket:
    """Connects to a Unix socket path or HOST:PORT, retrying until QEMU listens."""
    while True:
        try:
            if ":" in where and os.path.sep not in where:
                host, port = where.rsplit(":", 1)
                return socket.create_connection((host, int(port)), timeout=2)
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            sock.connect(where)
            return sock
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


def main() -> int:
    where = sys.argv[1] if len(sys.argv) > 1 else "/tmp/lssi-uart.sock"
    sock = connect(where, time.monotonic() + 20)
    sock.settimeout(10)
    sock.sendall(frame(HELLO))
    received = bytearray()
    try:
        while b"\x00" not in received:
            chunk = sock.recv(256)
            if not chunk:
                break
            received += chunk
    except socket.timeout:
        pass
    encoded = bytes(received).split(b"\x00")[0]
    decoded = cobs_decode(encoded)
    payload, crc = decoded[:-4], decoded[-4:]
    if len(decoded) < 5 or crc32c(payload).to_bytes(4, "little") != crc:
        print(f"hello: bad or no frame back: {bytes(received).hex()}")
        return 1
    if payload != HELLO_REPLY:
        print(f"hello: unexpected reply {payload.hex()}, wanted {HELLO_REPLY.hex()}")
        return 1
    print(f"hello ok: protocol {PROTOCOL_VERSION}, window capacity 256, 16 terms, batches of 24")
    return 0


if __name__ == "__main__":
    sys.exit(main())
