"""docs/wire-format.md matches the message types, and a decoder written from it alone reads every
envelope version of every type."""

from __future__ import annotations

import pytest

from tests.wire import spec_decoder
from tests.wire.samples import every_type, example, same
from umbra.connectors.codec import Codec
from umbra.runtime.links.wire_spec import DOC, missing_notes, render


def test_the_field_tables_are_those_of_the_message_types() -> None:
    types = every_type()
    assert len(types) >= 23
    assert missing_notes(types) == [], "document the new fields in their type's FIELD_NOTES"
    text = DOC.read_text()
    assert render(text, types) == text, "run `python -m umbra.runtime.links.wire_spec --write`"


def test_the_spec_names_every_field_in_wire_order() -> None:
    layouts = spec_decoder.layouts(DOC.read_text())
    for name, cls in every_type().items():
        tag, fields = layouts[name]
        assert fields[:3] == ["stamp", "seq", "origin"]
        assert fields == list(cls.__struct_fields__), name
        assert tag.startswith(f"{name}/")


@pytest.mark.parametrize("version", [1, 2, 3])
def test_every_type_decodes_from_the_spec_in_every_envelope(version: int) -> None:
    codec, layouts = Codec(), spec_decoder.layouts(DOC.read_text())
    encode = {1: codec.encode, 2: codec.encode_framed, 3: codec.encode_compact}[version]
    framed = 0
    for name, cls in every_type().items():
        msg = example(cls)
        got_name, got_version, fields = spec_decoder.decode(encode(msg), layouts)
        assert got_name == name
        if version == 2:  # only samples with 16 KiB of arrays or more are framed
            framed += got_version == 2
            assert got_version in (2, 3)
        else:
            assert got_version == version
        assert same(fields, msg) == [], name
    if version == 2:
        assert framed == 2  # Image and StereoSnapshot


def test_the_decoder_refuses_another_layout_and_unknown_versions() -> None:
    codec, layouts = Codec(), spec_decoder.layouts(DOC.read_text())
    data = codec.encode_compact(example(every_type()["Twist"]))
    tag = layouts["Twist"][0].encode()
    forged = data.replace(tag, b"Twist/00000000")
    with pytest.raises(spec_decoder.SpecError, match="layout Twist/00000000"):
        spec_decoder.decode(forged, layouts)
    with pytest.raises(spec_decoder.SpecError, match="version 9"):
        spec_decoder.decode(data.replace(b"\x03", b"\x09", 1), layouts)
