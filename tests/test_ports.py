"""The tests' free ports lie below the ephemeral range, so no socket bound to port 0 can take them."""

import socket

from ports import _ephemeral_low, free_tcp_port, free_udp_port


def test_free_ports_are_distinct_bindable_and_below_the_ephemeral_range():
    ports = [free_udp_port() for _ in range(20)] + [free_tcp_port() for _ in range(20)]
    assert all(port < _ephemeral_low() for port in ports)
    assert len(set(ports[:20])) == 20 and len(set(ports[20:])) == 20
    udp, tcp = ports[:20], ports[20:]
    held = []
    try:
        for kind, chosen in ((socket.SOCK_DGRAM, udp), (socket.SOCK_STREAM, tcp)):
            for port in chosen:
                sock = socket.socket(socket.AF_INET, kind)
                held.append(sock)
                sock.bind(("127.0.0.1", port))
        # sockets the kernel places (port 0) never land on them
        for _ in range(200):
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            held.append(sock)
            sock.bind(("127.0.0.1", 0))
            assert sock.getsockname()[1] >= _ephemeral_low()
    finally:
        for sock in held:
            sock.close()
