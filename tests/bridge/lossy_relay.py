"""A loopback UDP relay that drops, duplicates and reorders packets (seeded), for fault injection.

The vehicle sends to ``vehicle_port`` (the relay answers it at the address it last heard
from); the relay forwards to the ground station's ``udpin`` port ``gcs_port`` from an
ephemeral socket, and the ground station's answers go back the same way. Besides the random
faults, chosen packets can be dropped (``drop_if``) or delivered once more after the next
packet in the same direction (``duplicate_late_if``), and ``messages`` counts the MAVLink 2
messages that came in, by direction and message id.
"""

from __future__ import annotations

import collections
import select
import socket
import threading
import time
from collections.abc import Callable

import numpy as np
from ports import free_tcp_port, free_udp_port  # re-exported: the bridge tests import them from here

__all__ = ["LossyRelay", "free_udp_port", "free_tcp_port", "message_id", "TO_GCS", "TO_VEHICLE"]

HOST = "127.0.0.1"
TO_GCS, TO_VEHICLE = 0, 1  # directions


def message_id(data: bytes) -> int | None:
    """The message id of a MAVLink 2 packet, ``None`` for anything else."""
    return int.from_bytes(data[7:10], "little") if len(data) >= 12 and data[0] == 0xFD else None


class LossyRelay:
    """Relay UDP between a vehicle (sending to ``vehicle_port``) and a GCS ``udpin`` on ``gcs_port``.

    Args:
        gcs_port: The ground station's ``udpin`` port.
        rng: Source of the drop/duplicate/reorder decisions.
        drop: Probability that a packet is dropped.
        duplicate: Probability that a delivered packet is sent twice.
        reorder: Probability that a packet is held back and sent after the next one (or 20 ms).
        drop_if: ``drop_if(direction, packet)``: drop this packet (before any random fault).
        duplicate_late_if: ``duplicate_late_if(direction, packet)``: deliver it again after the
            next packet in the same direction (or 20 ms).
    """

    def __init__(
        self,
        gcs_port: int,
        rng: np.random.Generator,
        drop: float = 0.1,
        duplicate: float = 0.05,
        reorder: float = 0.05,
        drop_if: Callable[[int, bytes], bool] | None = None,
        duplicate_late_if: Callable[[int, bytes], bool] | None = None,
    ) -> None:
        self.rng = rng
        self.drop, self.duplicate, self.reorder = drop, duplicate, reorder
        self.drop_if, self.duplicate_late_if = drop_if, duplicate_late_if
        self.counts = {"in": 0, "dropped": 0, "duplicated": 0, "reordered": 0}
        self.messages: collections.Counter[tuple[int, int | None]] = collections.Counter()
        self._vehicle_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._vehicle_side.bind((HOST, 0))
        self.vehicle_port = self._vehicle_side.getsockname()[1]
        self._gcs_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._gcs_side.bind((HOST, 0))
        self._gcs_address = (HOST, gcs_port)
        self._vehicle_address: tuple[str, int] | None = None
        self._held: dict[int, tuple[bytes, float]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="lossy relay", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._vehicle_side.close()
        self._gcs_side.close()

    def __enter__(self) -> LossyRelay:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _deliver(self, direction: int, data: bytes) -> None:
        if direction == 0:
            self._gcs_side.sendto(data, self._gcs_address)
        elif self._vehicle_address is not None:
            self._vehicle_side.sendto(data, self._vehicle_address)

    def _forward(self, direction: int, data: bytes) -> None:
        self.counts["in"] += 1
        self.messages[direction, message_id(data)] += 1
        if self.drop_if is not None and self.drop_if(direction, data):
            self.counts["dropped"] += 1
            return
        if self.duplicate_late_if is not None and self.duplicate_late_if(direction, data):
            self._deliver(direction, data)
            self.counts["duplicated"] += 1
            self._held.setdefault(direction, (data, time.monotonic()))
            return
        if self.rng.random() < self.drop:
            self.counts["dropped"] += 1
            return
        copies = 2 if self.rng.random() < self.duplicate else 1
        self.counts["duplicated"] += copies - 1
        if direction not in self._held and self.rng.random() < self.reorder:
            self.counts["reordered"] += 1
            self._held[direction] = (data, time.monotonic())
            return
        for _ in range(copies):
            self._deliver(direction, data)
        if direction in self._held:
            self._deliver(direction, self._held.pop(direction)[0])

    def _loop(self) -> None:
        sockets = [self._vehicle_side, self._gcs_side]
        while not self._stop.is_set():
            ready, _, _ = select.select(sockets, [], [], 0.005)
            try:
                for sock in ready:
                    data, address = sock.recvfrom(65535)
                    if sock is self._vehicle_side:
                        self._vehicle_address = address
                        self._forward(0, data)
                    else:
                        self._forward(1, data)
                now_s = time.monotonic()
                for direction, (data, held_s) in list(self._held.items()):
                    if now_s - held_s > 0.02:
                        del self._held[direction]
                        self._deliver(direction, data)
            except OSError:
                continue
