#!/usr/bin/env python3
"""Checks that the firmware echoes UART0: connects to QEMU's UART socket, sends bytes and
expects the same bytes back.

    LSSI_SERIAL="-serial unix:/tmp/lssi-uart.sock,server=on,wait=off" cargo run --release &
    python3 scripts/uart_echo_check.py /tmp/lssi-uart.sock

Also takes HOST:PORT for `-serial tcp:127.0.0.1:PORT,server=on,wait=off`. Exits 0 when every
byte came back in order, 1 otherwise.
"""

import os
import socket
import sys
import time


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
    sock.settimeout(5)
    # Every byte value, then a line of text: the link is 8-bit clean.
    message = bytes(range(256)) + b"lssi echo check\n"
    received = bytearray()
    # The UART holds one byte each way; send in small chunks so nothing waits on a full pipe.
    for start in range(0, len(message), 16):
        chunk = message[start : start + 16]
        sock.sendall(chunk)
        want = start + len(chunk)
        while len(received) < want:
            data = sock.recv(4096)
            if not data:
                break
            received.extend(data)
    sock.close()
    if bytes(received) == message:
        print(f"echo ok: {len(message)} bytes")
        return 0
    print(f"echo FAILED: sent {len(message)} bytes, got {len(received)} back", file=sys.stderr)
    for i, (a, b) in enumerate(zip(message, received)):
        if a != b:
            print(f"first difference at byte {i}: sent {a:#04x}, got {b:#04x}", file=sys.stderr)
            break
    return 1


if __name__ == "__main__":
    sys.exit(main())
