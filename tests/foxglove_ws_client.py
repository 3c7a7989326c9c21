"""A small client of the Foxglove WebSocket protocol (v1) for tests, on the ``websockets`` library.

It speaks what the Foxglove app speaks to a live server: it offers the subprotocols
``foxglove.sdk.v1`` (the name the Foxglove SDK's server answers to) and ``foxglove.websocket.v1``,
reads ``serverInfo`` and ``advertise`` (JSON text frames), sends ``subscribe`` and reads the binary
``messageData`` frames: opcode 1, subscription id (uint32), log time (uint64 ns), payload, little
endian. Payloads are decoded with the schema each channel advertised (``foxglove_readback.decode``).
"""

from __future__ import annotations

import base64
import json
import socket
import struct
import time
from types import SimpleNamespace
from typing import Any

from foxglove_readback import decode
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

__all__ = ["SUBPROTOCOLS", "LiveClient"]

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
_MESSAGE_DATA = 0x01
_HEADER = struct.Struct("<BIQ")


class LiveClient:
    """One client connection to ``ws://127.0.0.1:<port>``, retried until the server listens.

    Args:
        port: The server's port on 127.0.0.1.
        attempts: Connection attempts, 0.1 s apart (the server may still be starting).
        receive_buffer_bytes: The socket's receive buffer (small: a client that stalls sooner).
    """

    def __init__(self, port: int, attempts: int = 1200, receive_buffer_bytes: int | None = None) -> None:
        for attempt in range(attempts):
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            if receive_buffer_bytes is not None:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer_bytes)
            try:
                sock.connect(("127.0.0.1", port))
                break
            except ConnectionRefusedError:
                sock.close()
                if attempt == attempts - 1:
                    raise
                time.sleep(0.1)
        self.ws = connect(f"ws://127.0.0.1:{port}", sock=sock, subprotocols=SUBPROTOCOLS, max_size=None,
                          open_timeout=60, compression=None, proxy=None, ping_interval=None,
                          legacy=True)
        self.server_info = json.loads(self.ws.recv(timeout=60))
        self.channels: dict[str, dict[str, Any]] = {}
        self._subscribed: dict[int, dict[str, Any]] = {}

    def close(self) -> None:
        """Close the connection."""
        self.ws.close()

    def wait_for(self, topics: list[str]) -> None:
        """Read ``advertise`` messages until every topic of ``topics`` is advertised."""
        while not set(topics) <= set(self.channels):
            self._take(self.ws.recv(timeout=60))

    def subscribe(self, topics: list[str]) -> None:
        """Subscribe to ``topics`` (advertised), in one ``subscribe`` message."""
        subscriptions = []
        for topic in topics:
            sub_id = len(self._subscribed) + 1
            self._subscribed[sub_id] = self.channels[topic]
            subscriptions.append({"id": sub_id, "channelId": self.channels[topic]["id"]})
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))

    def messages(self, timeout_s: float = 120.0) -> list[tuple[str, int, dict[str, Any]]]:
        """Every message until the server closes the connection: topic, log time (ns), decoded payload."""
        received = []
        try:
            while True:
                item = self._take(self.ws.recv(timeout=timeout_s))
                if item is not None:
                    received.append(item)
        except ConnectionClosed:
            return received

    def next_message(self, timeout_s: float = 60.0) -> tuple[str, int, dict[str, Any]]:
        """The next message of a subscribed topic."""
        while True:
            item = self._take(self.ws.recv(timeout=timeout_s))
            if item is not None:
                return item

    def _take(self, frame: str | bytes) -> tuple[str, int, dict[str, Any]] | None:
        if isinstance(frame, str):
            op = json.loads(frame)
            if op["op"] == "advertise":
                self.channels |= {c["topic"]: c for c in op["channels"]}
            return None
        opcode, sub_id, log_ns = _HEADER.unpack_from(frame)
        assert opcode == _MESSAGE_DATA, f"unexpected binary opcode {opcode}"
        channel = self._subscribed[sub_id]
        data = channel["schema"].encode()
        if channel["schemaEncoding"] == "protobuf":
            data = base64.b64decode(channel["schema"])
        schema = SimpleNamespace(name=channel["schemaName"], encoding=channel["schemaEncoding"], data=data)
        return channel["topic"], log_ns, decode(schema, bytes(frame[_HEADER.size:]))
