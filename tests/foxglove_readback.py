"""Read a recording back without the Foxglove SDK: the ``mcap`` reader, protobuf's own decoder, JSON.

A ``foxglove.*`` message (protobuf, its descriptors written in the file) is decoded into the JSON form
of Foxglove's published JSON Schemas (``tests/data/foxglove_schemas``): times as ``{sec, nsec}``,
bytes as base64 text, enums as integers, optional fields left out when unset. :func:`conform` checks
such a message against the published definition: every field name it has is declared there (at every
depth), every required one is present, and every value has the declared type (``jsonschema``).
"""

from __future__ import annotations

import base64
import json
from functools import cache
from pathlib import Path
from typing import Any

import jsonschema
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.descriptor import FieldDescriptor
from mcap.reader import make_reader

__all__ = ["PUBLISHED", "read_back", "decode", "conform"]

_SCHEMAS = Path(__file__).parent / "data" / "foxglove_schemas"
PUBLISHED = {f"foxglove.{p.stem}": json.loads(p.read_text()) for p in _SCHEMAS.glob("*.json")}
"""Foxglove's published JSON Schema of each message type a recording uses, by its name."""

_TIMES = {"google.protobuf.Timestamp", "google.protobuf.Duration"}


@cache
def _message_class(name: str, descriptor_set: bytes) -> Any:
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(descriptor_set).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def _value(field: FieldDescriptor, value: Any) -> Any:
    if field.type == FieldDescriptor.TYPE_MESSAGE:
        return _json_form(value)
    if field.type == FieldDescriptor.TYPE_BYTES:
        return base64.b64encode(value).decode("ascii")
    return value  # enums are their integers; numbers, strings and booleans as they are


def _json_form(message: Any) -> dict[str, Any]:
    if message.DESCRIPTOR.full_name in _TIMES:
        return {"sec": message.seconds, "nsec": message.nanos}
    out: dict[str, Any] = {}
    for field in message.DESCRIPTOR.fields:
        value = getattr(message, field.name)
        if field.is_repeated:
            out[field.name] = [_value(field, v) for v in value]
        elif not field.has_presence or message.HasField(field.name):
            out[field.name] = _value(field, value)
    return out


def decode(schema: Any, data: bytes) -> dict[str, Any]:
    """A message of the file as a dict: JSON as it is, protobuf in the published JSON form."""
    if schema.encoding == "protobuf":
        return _json_form(_message_class(schema.name, schema.data).FromString(data))
    return json.loads(data)


def read_back(path: Path) -> dict[str, Any]:
    """Everything in the file, by topic: schemas, encodings, log times and decoded messages."""
    with path.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        topics: dict[str, dict[str, Any]] = {}
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            topic = topics.setdefault(channel.topic, {
                "schema": schema.name, "schema_encoding": schema.encoding, "schema_data": schema.data,
                "encoding": channel.message_encoding, "log_ns": [], "publish_ns": [], "messages": []})
            topic["log_ns"].append(message.log_time)
            topic["publish_ns"].append(message.publish_time)
            topic["messages"].append(decode(schema, message.data))
    return {"summary": summary, "metadata": metadata, "topics": topics}


def _names(value: Any, schema: dict[str, Any], where: str) -> list[str]:
    """Field names of ``value`` that ``schema`` does not declare, and required ones it lacks."""
    wrong: list[str] = []
    if isinstance(value, dict) and "properties" in schema:
        declared = schema["properties"]
        wrong += [f"{where}.{k}: not in the published schema" for k in value if k not in declared]
        wrong += [f"{where}.{k}: required, missing" for k in schema.get("required", []) if k not in value]
        for key, item in value.items():
            if key in declared:
                wrong += _names(item, declared[key], f"{where}.{key}")
    elif isinstance(value, list) and "items" in schema:
        for i, item in enumerate(value):
            wrong += _names(item, schema["items"], f"{where}[{i}]")
    return wrong


def conform(message: dict[str, Any], schema_name: str) -> list[str]:
    """What in ``message`` departs from Foxglove's published ``schema_name`` (empty: it conforms)."""
    published = PUBLISHED[schema_name]
    wrong = _names(message, published, schema_name)
    wrong += [f"{schema_name}{'.'.join(map(str, e.absolute_path))}: {e.message}"
              for e in jsonschema.Draft202012Validator(published).iter_errors(message)]
    return wrong
