"""The FMUs' GUID: a fingerprint of the model description and the code behind it, the same for the same build.

FMI 2.0 defines the GUID as a fingerprint of the model description that ties it
to its binaries ("a checksum of the xml file could be used").  A time-based or
random GUID changes with every build: the native binaries, which check it,
would differ in every build, and no two builds of the same model could be
compared byte for byte or take their binaries from the compile cache
(:mod:`hammerbit.fmu.compile_cache`).  :func:`content_guid` hashes the model
description (without its GUID and generation time) and the hash of the code
the FMU runs, so that any change to either gives a new GUID.
"""
from __future__ import annotations

import hashlib
import re
import uuid
from xml.etree import ElementTree as ET

__all__ = ["GUID_NAMESPACE", "content_guid", "replace_guid"]

#: the namespace of the name-based (version 5) UUIDs of hammerbit's FMUs
GUID_NAMESPACE = uuid.uuid5(uuid.NAMESPACE_URL, "https://github.com/hammerbit/hammerbit/fmu")
_ATTRIBUTES_LEFT_OUT = ("guid", "instantiationToken", "generationDateAndTime")


def content_guid(model_description: bytes, code_hash: str) -> str:
    """A version-5 UUID of ``model_description`` (its ``guid`` and ``generationDateAndTime`` left
    out) and ``code_hash`` (a hash of the sources the FMU's binaries or runtime are built from)."""
    root = ET.fromstring(model_description)
    for name in _ATTRIBUTES_LEFT_OUT:
        root.attrib.pop(name, None)
    digest = hashlib.sha256(ET.tostring(root, encoding="utf-8") + b"\0" + code_hash.encode()).hexdigest()
    return str(uuid.uuid5(GUID_NAMESPACE, digest))


def replace_guid(model_description: bytes, guid: str) -> bytes:
    """``model_description`` with the ``guid`` attribute of its root set to ``guid`` (the text
    otherwise unchanged)."""
    new, n = re.subn(rb'(<fmiModelDescription\b[^>]*?\sguid=")[^"]*(")',
                     lambda m: m.group(1) + guid.encode() + m.group(2), model_description, count=1)
    if n != 1:
        raise ValueError("the model description has no guid attribute on <fmiModelDescription>")
    return new
