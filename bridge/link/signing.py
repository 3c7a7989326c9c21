"""MAVLink 2 signing keys, read from a file or an environment variable and never logged."""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Mapping
from pathlib import Path

from bridge.config import SigningConfig
from typed_config import ConfigError

__all__ = ["SigningKey", "load_signing_key"]

_HEX_KEY = re.compile(r"[0-9a-fA-F]{64}")


class SigningKey:
    """A 32-byte MAVLink 2 signing key whose ``repr``/``str`` never show the secret."""

    __slots__ = ("_secret",)

    def __init__(self, secret: bytes) -> None:
        if len(secret) != 32:
            raise ValueError(f"a MAVLink signing key has 32 bytes, got {len(secret)}")
        self._secret = bytes(secret)

    @classmethod
    def from_text(cls, text: str) -> SigningKey:
        """64 hex digits are the key itself; any other text is a passphrase hashed with SHA-256."""
        text = text.strip()
        if not text:
            raise ValueError("the signing key text is empty")
        if _HEX_KEY.fullmatch(text):
            return cls(bytes.fromhex(text))
        return cls(hashlib.sha256(text.encode("utf-8")).digest())

    @property
    def secret(self) -> bytes:
        """The raw key, for ``setup_signing`` only."""
        return self._secret

    def __repr__(self) -> str:
        return "SigningKey(<hidden>)"

    __str__ = __repr__


def load_signing_key(config: SigningConfig, environ: Mapping[str, str] | None = None) -> SigningKey | None:
    """The configured signing key, or ``None`` when signing is off.

    Args:
        config: Where the key lives.
        environ: Environment to read ``config.key_env`` from (default: ``os.environ``).

    Raises:
        ConfigError: The file or variable is missing or empty (the message never holds the key).
    """
    if config.key_env:
        value = (os.environ if environ is None else environ).get(config.key_env, "")
        if not value.strip():
            raise ConfigError(
                f"SigningConfig.key_env: environment variable {config.key_env} is unset or empty"
            )
        return SigningKey.from_text(value)
    if config.key_file:
        path = Path(config.key_file).expanduser()
        try:
            raw = path.read_bytes()
        except OSError as exc:
            raise ConfigError(f"SigningConfig.key_file: cannot read {path}: {exc.strerror}") from None
        if len(raw) == 32:
            return SigningKey(raw)
        try:
            return SigningKey.from_text(raw.decode("utf-8"))
        except (UnicodeDecodeError, ValueError):
            raise ConfigError(
                f"SigningConfig.key_file: {path} must hold 32 raw bytes, 64 hex digits or a passphrase"
            ) from None
    return None
