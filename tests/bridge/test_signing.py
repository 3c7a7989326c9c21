import hashlib
import logging

import pytest

from bridge.config import SigningConfig
from bridge.link.signing import SigningKey, load_signing_key
from typed_config import ConfigError

HEX = "00112233445566778899aabbccddeeff" * 2


def test_key_from_env_hex_and_passphrase():
    key = load_signing_key(SigningConfig(key_env="UAV_KEY"), environ={"UAV_KEY": HEX})
    assert key.secret == bytes.fromhex(HEX)
    key = load_signing_key(SigningConfig(key_env="UAV_KEY"), environ={"UAV_KEY": "swarm passphrase\n"})
    assert key.secret == hashlib.sha256(b"swarm passphrase").digest()


def test_key_from_file_raw_or_text(tmp_path):
    raw = tmp_path / "raw.key"
    raw.write_bytes(bytes(range(32)))
    assert load_signing_key(SigningConfig(key_file=str(raw))).secret == bytes(range(32))
    text = tmp_path / "hex.key"
    text.write_text(HEX + "\n")
    assert load_signing_key(SigningConfig(key_file=str(text))).secret == bytes.fromhex(HEX)


def test_no_key_source_means_no_signing():
    assert load_signing_key(SigningConfig()) is None
    assert not SigningConfig().enabled


def test_missing_key_is_a_config_error_without_the_secret(tmp_path):
    with pytest.raises(ConfigError, match="UAV_KEY is unset or empty"):
        load_signing_key(SigningConfig(key_env="UAV_KEY"), environ={})
    with pytest.raises(ConfigError, match="cannot read"):
        load_signing_key(SigningConfig(key_file=str(tmp_path / "missing.key")))


def test_key_never_shows_in_repr_or_logs(caplog):
    key = SigningKey.from_text(HEX)
    with caplog.at_level(logging.DEBUG):
        logging.getLogger("bridge").info("key %s %r", key, key)
    assert HEX not in caplog.text and "00112233" not in caplog.text and "hidden" in caplog.text
    with pytest.raises(ValueError, match="32 bytes"):
        SigningKey(b"short")
