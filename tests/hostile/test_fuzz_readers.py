"""Property-based fuzzing of every reader of user input: whatever the bytes, a reader returns a
value or raises the user error of its kind, whose message starts ``SOURCE[:LINE[:COL]]: error:``.
Nothing else escapes, and nothing runs away (each example has a deadline).

Inputs are valid files mutated at random (bytes replaced, inserted, deleted, lines duplicated)
and documents assembled from the tokens that break parsers (anchors, aliases, tags, brackets,
huge numbers, odd encodings). Few examples per reader, derandomized: the default test run stays
quick and stable; the hostile corpus (test_corpus.py) holds the hand-made cases.
"""

from __future__ import annotations

import json
import re
import tempfile
from datetime import timedelta
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from umbra.connectors.cli_support import parse_value
from umbra.connectors.errors import UserError
from umbra.connectors.safe_yaml import load
from umbra.connectors.user_files import decode_text
from umbra.modules.arm.cia402.config_yaml import settings_from_yaml_text
from umbra.modules.arm.dh import DHError
from umbra.modules.arm.dh_yaml import dh_table_from_yaml_text
from umbra.modules.calib.camera_file import parse_cameras
from umbra.modules.calib.correspondences import parse_correspondences
from umbra.modules.calib.pose_tool_file import parse_session
from umbra.modules.calib.zoom_xml import parse_zoom_xml
from umbra.modules.calib.zoom_yaml import parse_zoom_yaml
from umbra.modules.vision.image_file import read_image
from umbra.runtime.graph.check import check_text
from umbra.runtime.graph.names import endpoint_problem, key_prefix_problem, plain_beyond_host
from umbra.runtime.links.auth import load_auth
from umbra.runtime.links.config import Endpoints, build_config

CORPUS = Path(__file__).parent / "corpus"
REPO = Path(__file__).resolve().parents[2]
FUZZ = settings(
    max_examples=25,
    deadline=timedelta(seconds=5),
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
TOKENS = [
    "a",
    "b: ",
    "- ",
    "  ",
    "\n",
    ":",
    ",",
    "[",
    "]",
    "{",
    "}",
    "&x ",
    "*x",
    "&y ",
    "*y",
    "<<: *x",
    "!!float ",
    "!!int ",
    "!!binary ",
    "!!python/object:os.system ",
    "!!timestamp ",
    "!!set ",
    "? ",
    "'",
    '"',
    "#",
    "|",
    ">",
    "---",
    "...",
    "%YAML 1.1",
    "\t",
    "\x00",
    "\ufeff",
    "é",
    ".inf",
    "-.inf",
    ".nan",
    "1e999",
    "Infinity",
    "1234567890" * 500,  # a 5000-digit number: beyond int() of a string
    "0x1F",
    "0o17",
    "1_000",
    "~",
    "null",
    "true",
    "joints",
    "name",
    "cameras",
    "graph",
    "modules",
    "type",
    "rate",
    "params",
]


def documents() -> st.SearchStrategy[str]:
    """Documents assembled from parser-breaking tokens."""
    return st.lists(st.sampled_from(TOKENS), max_size=60).map("".join)


def mutated(valid: bytes) -> st.SearchStrategy[bytes]:
    """``valid`` with a few random edits: replaced, inserted or deleted bytes, a repeated line."""

    def apply(edits: list[tuple[int, int, int]]) -> bytes:
        data = bytearray(valid)
        for kind, where, value in edits:
            at = where % (len(data) + 1)
            if kind == 0 and data:
                data[min(at, len(data) - 1)] = value
            elif kind == 1:
                data.insert(at, value)
            elif kind == 2 and data:
                del data[min(at, len(data) - 1)]
            elif kind == 3:
                lines = bytes(data).split(b"\n")
                i = at % len(lines)
                data = bytearray(b"\n".join([*lines[: i + 1], lines[i], *lines[i + 1 :]]))
        return bytes(data)

    edit = st.tuples(st.integers(0, 3), st.integers(0, 1 << 16), st.integers(0, 255))
    return st.lists(edit, min_size=1, max_size=6).map(apply)


def text_of(data: bytes) -> str:
    return data.decode("utf-8", "replace")


def located(message: str, source: str) -> bool:
    return re.match(rf"^{re.escape(source)}(:\d+){{0,2}}: error: ", message) is not None


def assert_user_error(call, source: str, errors: tuple[type[BaseException], ...] = (UserError,)):
    """Run ``call``: fine when it returns; if it raises, only ``errors`` with a located message."""
    try:
        call()
    except errors as exc:
        first = str(exc).splitlines()[0] if str(exc) else ""
        assert located(first, source), f"not a located error: {str(exc)!r}"


GRAPH_OK = (CORPUS / "graphs" / "set_base.yaml").read_bytes()
DH_OK = (CORPUS / "dh" / "ok.yaml").read_bytes()
ZOOM_XML = (REPO / "modules/calib/data/zoom_cam.xml").read_bytes()
ZOOM_YAML = (REPO / "modules/calib/data/zoom_cam.yaml").read_bytes()
CAMERAS = (CORPUS / "calib" / "cams_ok.yaml").read_bytes()
PAIRS = (CORPUS / "calib" / "pairs_ok.csv").read_bytes()
CANOPEN = b"""bus: {interface: virtual, channel: fuzz, bitrate: 500000}
simulate: true
joints:
  - {name: j1, node_id: 1, counts_per_rad: 10000}
  - {name: j2, node_id: 2, counts_per_rad: 10000, zero_counts: 5}
"""


@FUZZ
@given(st.one_of(mutated(GRAPH_OK), documents().map(str.encode)))
def test_graph_reader(data: bytes) -> None:
    assert_user_error(lambda: check_text(data, "g.yaml"), "g.yaml")


@FUZZ
@given(st.one_of(documents(), st.text(max_size=200)))
def test_generic_yaml_reader(text: str) -> None:
    assert_user_error(lambda: load(text, "f.yaml"), "f.yaml")


@FUZZ
@given(st.one_of(documents(), st.text(max_size=200)))
def test_set_values(text: str) -> None:
    assert_user_error(lambda: parse_value(text, "--set m.p"), "--set m.p")


@FUZZ
@given(st.one_of(mutated(DH_OK), documents().map(str.encode)))
def test_dh_reader(data: bytes) -> None:
    assert_user_error(
        lambda: dh_table_from_yaml_text(text_of(data), "dh.yaml"), "dh.yaml", (DHError, UserError)
    )


@FUZZ
@given(st.one_of(mutated(CANOPEN), documents().map(str.encode)))
def test_canopen_settings_reader(data: bytes) -> None:
    assert_user_error(
        lambda: settings_from_yaml_text(text_of(data), "bus.yaml", Path(tempfile.gettempdir())),
        "bus.yaml",
    )


@FUZZ
@given(st.one_of(mutated(ZOOM_XML), st.binary(max_size=300)))
def test_zoom_xml_reader(data: bytes) -> None:
    assert_user_error(lambda: parse_zoom_xml(data, "zoom.xml"), "zoom.xml")


@FUZZ
@given(st.one_of(mutated(ZOOM_YAML), documents().map(str.encode)))
def test_zoom_yaml_reader(data: bytes) -> None:
    assert_user_error(lambda: parse_zoom_yaml(text_of(data), "zoom.yaml"), "zoom.yaml")


@FUZZ
@given(st.one_of(mutated(CAMERAS), documents().map(str.encode)))
def test_cameras_reader(data: bytes) -> None:
    base = REPO / "modules/calib/data"
    assert_user_error(lambda: parse_cameras(text_of(data), "cams.yaml", base), "cams.yaml")


@FUZZ
@given(st.one_of(mutated(PAIRS), st.text(alphabet='0123456789.,-+eEinfa"#\n xyzuv', max_size=300)))
def test_correspondence_reader(data: bytes | str) -> None:
    text = data if isinstance(data, str) else text_of(data)
    assert_user_error(lambda: parse_correspondences(text, "pairs.csv"), "pairs.csv")


@FUZZ
@given(st.binary(max_size=200))
def test_text_decoding(data: bytes) -> None:
    assert_user_error(lambda: decode_text(data, "f.txt"), "f.txt")


@FUZZ
@given(st.one_of(mutated((CORPUS / "images" / "gray.png").read_bytes()), st.binary(max_size=200)))
def test_image_reader(data: bytes) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "image.png"
        path.write_bytes(data)
        try:
            image = read_image(path)
        except UserError as exc:
            assert located(str(exc), str(path)), str(exc)
        else:
            assert image.ndim == 3 and image.shape[2] == 3


@FUZZ
@given(st.text(max_size=80))
def test_key_prefixes_and_endpoints(text: str) -> None:
    """The checks answer with text for anything; what they accept has no zenoh wildcard."""
    if not key_prefix_problem(text):
        assert not set("*$?#") & set(text) and "//" not in text
    if not endpoint_problem(text):  # a valid endpoint is judged without failing
        assert isinstance(plain_beyond_host(text), bool)


SESSION_OK = b"""mount: flange->camera
camera: {fx: 800, fy: 800, skew: 0, u0: 320, v0: 240, k1: 0, k2: 0, p1: 0, p2: 0, k3: 0}
points:
  a: [0.1, 0.0, 0.5]
  b: [0.0, 0.1, 0.5]
  c: [-0.1, 0.0, 0.6]
snapshots:
  - parent: {xyz: [0, 0, 0], rpy_deg: [0, 0, 0]}
    clicks: {a: [480.0, 240.0], b: [320.0, 400.0], c: [186.7, 240.0]}
"""


@FUZZ
@given(st.one_of(mutated(SESSION_OK), documents().map(str.encode)))
def test_pose_tool_session_reader(data: bytes) -> None:
    assert_user_error(lambda: parse_session(text_of(data), "session.yaml"), "session.yaml")


CREDENTIALS_OK = b'{"user": "smart", "password": "0123abcd", "dictionary_file": "d.txt"}'


@FUZZ
@given(st.one_of(mutated(CREDENTIALS_OK), st.binary(max_size=200)))
def test_link_credentials_reader(data: bytes) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "auth.json"
        path.write_bytes(data)
        path.chmod(0o600)
        assert_user_error(lambda: load_auth(str(path)), str(path))


ZENOH_OK = b"""{
  mode: "peer",
  transport: {link: {tls: {root_ca_certificate: "ca.pem", enable_mtls: true}}},
  access_control: {enabled: false, default_permission: "deny"},
}
"""


@FUZZ
@given(st.one_of(mutated(ZENOH_OK), st.binary(max_size=200)))
def test_zenoh_configuration_reader(data: bytes) -> None:
    """A user's zenoh file: read, or refused naming the file; endpoints and safety settings are
    always ours (scouting stays off)."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "z.json5"
        path.write_bytes(data)
        try:
            cfg = build_config(Endpoints(listen=["tcp/127.0.0.1:0"]), str(path))
        except UserError as exc:
            assert located(str(exc), str(path)) and "\n" not in str(exc), str(exc)
        else:
            assert cfg.get_json("scouting/multicast/enabled") == "false"
            assert cfg.get_json("listen/endpoints") == '["tcp/127.0.0.1:0"]'


def _recording_ok() -> bytes:
    """A small finished recording written by the recorder: Scalars, a JPEG camera image, a pose."""
    import numpy as np

    from umbra.connectors.messages import Image, Pose, Scalar
    from umbra.runtime.recording.writer import RecordingFile

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "ok.mcap"
        rec = RecordingFile(path, blocking=True, chunk_size=512)
        rec.declare("/camera/image", Image, {"umbra.role": "primary"}, images="jpeg")
        pixels = np.random.default_rng(1).integers(0, 255, (12, 16, 3), dtype=np.uint8)
        for i in range(6):
            t = i * 0.1
            rec.offer("/src/value", Scalar(value=float(i), stamp=t, seq=i + 1), t)
            rec.offer("/camera/image", Image(pixels=pixels, frame="camera", stamp=t, seq=i + 1), t)
            rec.offer("/kin/pose", Pose(matrix=np.eye(4), parent="base", child="tool", stamp=t), t)
        rec.close()
        return path.read_bytes()


RECORDING_OK = _recording_ok()
MCAP_MAGIC = b"\x89MCAP0\r\n"


def _read_recording_every_way(path: Path) -> None:
    """Every reader of recordings: read through, indexed, decoded samples and record-info."""
    from umbra.runtime.recording.info import recording_info
    from umbra.runtime.recording.reader import indexed_scan, read_messages, read_records
    from umbra.runtime.recording.samples import iter_samples

    sum(1 for _ in read_records(path))
    scan = indexed_scan(path)
    sum(1 for _ in read_messages(path, None, scan))
    sum(1 for _ in iter_samples(path, None, scan))
    recording_info(path)


@FUZZ
@given(
    st.one_of(mutated(RECORDING_OK), st.binary(max_size=300).map(lambda b: b"\x89MCAP0\r\n" + b))
)
def test_recording_readers(data: bytes) -> None:
    """A mutated recording: read, or a located UserError (samples that do not decode are a
    ValueError the replay turns into one, naming the file)."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "rec.mcap"
        path.write_bytes(data)
        try:
            _read_recording_every_way(path)
        except UserError as exc:
            assert located(str(exc), str(path)), str(exc)
        except ValueError as exc:  # decode_primary: a sample's bytes are not its type
            assert "Traceback" not in str(exc)


def test_the_valid_recording_reads_every_way() -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "rec.mcap"
        path.write_bytes(RECORDING_OK)
        _read_recording_every_way(path)


_PLACE = {"cmd": "place", "kind": "line", "a": ["1,2", "3,4"], "b": ["5,6", "7,8"]}
SKETCH_SESSION_OK = json.dumps(
    {
        "seed": 3,
        "events": [
            {"cmd": "aim", "xyz": [0.5, 0.0, 0.3], "at": None, "zoom": 0.2},
            {"cmd": "snapshot"},
            {**_PLACE, "truth": None, "noise": 0.5, "seed": 1},
            {"cmd": "plan", "macro": "grab_pipe", "primitive": "line1", "options": {"d": 0.1}},
            {"cmd": "play", "path": "path1", "script": [[0.0, "play", None]], "timeout": 60.0},
        ],
    },
    indent=1,
).encode()
JSON_TOKENS = ["{", "}", "[", "]", ":", ",", '"seed"', '"events"', '"cmd"', '"aim"', '"play"']
JSON_TOKENS += ['"script"', "3", "-1", "1e999", "NaN", "null", "true", '"\\u0000"', '"é"', "\n"]


@FUZZ
@given(
    st.one_of(
        mutated(SKETCH_SESSION_OK),
        st.lists(st.sampled_from(JSON_TOKENS), max_size=60).map(lambda t: "".join(t).encode()),
    )
)
def test_sketch_session_reader(data: bytes) -> None:
    from umbra.modules.sketch.session_file import parse_session_state

    assert_user_error(lambda: parse_session_state(data, "session.json"), "session.json")
