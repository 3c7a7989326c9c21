"""Listen endpoints are tried before a Zenoh session opens; one in use is named with its cause."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import pytest

from bridge.telemetry.config import (
    DEFAULT_ENDPOINT,
    TelemetryConfig,
    TelemetryConnectionError,
    check_listen_endpoints,
    listen_elsewhere_if_taken,
    open_session,
)
from uav_swarm.cli import main


@pytest.fixture()
def held_port() -> Iterator[int]:
    """A loopback TCP port another socket listens on for the test."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.listen(1)
        yield sock.getsockname()[1]


def _listen(*endpoints: str) -> TelemetryConfig:
    return TelemetryConfig(swarm="probe", listen=endpoints)


def test_an_endpoint_in_use_is_named_with_its_cause(held_port):
    endpoint = f"tcp/127.0.0.1:{held_port}"
    with pytest.raises(TelemetryConnectionError, match=f"^{endpoint} is in use"):
        check_listen_endpoints(_listen(endpoint))


def test_a_port_bound_without_listening_is_in_use_too():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        endpoint = f"tcp/127.0.0.1:{sock.getsockname()[1]}"
        with pytest.raises(TelemetryConnectionError, match="is in use"):
            check_listen_endpoints(_listen(endpoint))


def test_a_udp_endpoint_in_use_is_found():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        endpoint = f"udp/127.0.0.1:{sock.getsockname()[1]}"
        with pytest.raises(TelemetryConnectionError, match=f"{endpoint} is in use"):
            check_listen_endpoints(_listen(endpoint))


def test_a_free_port_and_the_connections_a_previous_run_left_in_time_wait_pass():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as server:
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        port = server.getsockname()[1]
        client = socket.create_connection(("127.0.0.1", port))
        accepted, _ = server.accept()
        accepted.close()  # the listening side closes first: its end stays in TIME_WAIT
        client.recv(1)
        client.close()
    check_listen_endpoints(_listen(f"tcp/127.0.0.1:{port}"))  # Zenoh can listen there again
    check_listen_endpoints(_listen(f"tcp/127.0.0.1:{port}"))  # and the probe leaves nothing behind


def test_an_address_of_another_machine_is_reported():
    with pytest.raises(TelemetryConnectionError, match="192.0.2.1 is not an address of this machine"):
        check_listen_endpoints(_listen("tcp/192.0.2.1:7447"))


def test_port_zero_and_endpoints_without_ports_are_not_probed(held_port):
    check_listen_endpoints(_listen("tcp/127.0.0.1:0", "unixsock-stream//tmp/probe.sock"))
    check_listen_endpoints(TelemetryConfig(listen=(), connect=(f"tcp/127.0.0.1:{held_port}",)))


def test_open_session_fails_at_once_instead_of_at_zenohs_timeout(held_port):
    endpoint = f"tcp/127.0.0.1:{held_port}"
    start = time.monotonic()
    with pytest.raises(TelemetryConnectionError, match=f"{endpoint} is in use"):
        open_session(TelemetryConfig(swarm="probe", listen=(endpoint,), timeout_s=10.0))
    assert time.monotonic() - start < 2.0


def test_telemetry_watch_listening_on_a_port_in_use_exits_2(held_port, capsys):
    endpoint = f"tcp/127.0.0.1:{held_port}"
    assert main(["telemetry", "watch", "--listen", endpoint, "--count", "1"]) == 2
    assert f"{endpoint} is in use" in capsys.readouterr().err


@pytest.fixture()
def default_port_taken() -> Iterator[None]:
    """127.0.0.1:7447 held for the test (by this test, or already by another run on this machine)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        try:
            sock.bind(("127.0.0.1", 7447))
            sock.listen(1)
        except OSError:
            pass  # someone else holds it: taken all the same
        yield


def test_a_run_left_at_the_default_endpoint_moves_to_a_free_port_when_it_is_taken(default_port_taken):
    config, line = listen_elsewhere_if_taken(TelemetryConfig(swarm="probe"))
    (endpoint,) = config.listen
    assert endpoint.startswith("tcp/127.0.0.1:") and endpoint != DEFAULT_ENDPOINT
    assert line == (f"{DEFAULT_ENDPOINT} is in use (another run?): telemetry listens on {endpoint} instead "
                    f"(uav-swarm telemetry watch --connect {endpoint})")
    check_listen_endpoints(config)  # free now
    assert config.swarm == "probe"


def test_an_endpoint_given_is_never_moved(held_port):
    given = _listen(f"tcp/127.0.0.1:{held_port}")
    assert listen_elsewhere_if_taken(given) == (given, None)
