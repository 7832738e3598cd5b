# ruff: noqa: E501 -- a table of cases: one case a line reads best
"""Writes the hostile-input corpus (tests/hostile/corpus/) and its manifest.

Run ``python tests/hostile/make_corpus.py`` after changing a case; the files it writes are
checked in, so the test reads them as a user's files are read. Each case of ``manifest.yaml``:
``id``, ``argv`` (the ``umbra`` command line, run in the corpus folder; ``{tmp}`` is a fresh
folder, ``{fifo}`` a named pipe in it, ``{repo}`` the checkout), ``status`` (exit status) and
``error`` (a regular expression one line of stderr must match).
"""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path

HERE = Path(__file__).parent / "corpus"

ARM_GRAPH = """graph: hostile_arm
frames:
  tool->camera: {xyz: [0.0, 0.06, 0.04], rpy_deg: [0, 0, 90]}
modules:
  vision: {type: TwistSource, rate: 100, params: {twist: [0.02, 0, 0, 0, 0, 0.1]}}
  reg: {type: REG_VEL, rate: 100, params: {timeout: 0.1}}
  rot: {type: ROTATE_KIN}
  kin: {type: WOLVERINE_KIN}
  jnts: {type: WOLVERINE_JNTS, rate: 100, params: {initial_q_deg: [10, 50, -170, 5, 40, 15]}}
connections:
  - vision.twist -> reg.command
  - reg.twist -> rot.camera_twist
  - rot.tool_twist -> kin.tool_twist
  - kin.joint_rates -> jnts.rates
  - jnts.joint_state ~> kin.joint_state
"""

DH_OK = """name: two_link
joints:
  - {name: j1, d: 0.3, a: 0.2, alpha_deg: 0, limits_deg: [-170, 170], max_rate_deg: 90}
  - {name: j2, d: 0.0, a: 0.2, alpha_deg: 0, limits_deg: [-170, 170], max_rate_deg: 90}
"""

CASES: list[dict] = []


def case(case_id: str, argv: list[str], status: int, error: str) -> None:
    CASES.append({"id": case_id, "argv": argv, "status": status, "error": error})


def write(rel: str, content: str | bytes) -> str:
    path = HERE / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return rel


def arm(replace: dict[str, str]) -> str:
    text = ARM_GRAPH
    for old, new in replace.items():
        assert old in text, old
        text = text.replace(old, new)
    return text


def line_of(text: str, needle: str) -> int:
    return text[: text.index(needle)].count("\n") + 1


def graph_case(name: str, replace: dict[str, str], needle: str, error: str) -> None:
    """A graph that differs from ARM_GRAPH by ``replace``; the error is at ``needle``'s line."""
    text = arm(replace)
    rel = write(f"graphs/{name}.yaml", text)
    line = line_of(text, needle)
    case(
        f"graph-{name}", ["check", rel], 2, rf"^graphs/{name}\.yaml:{line}(:\d+)?: error: .*{error}"
    )


def raw_graph(name: str, content: str | bytes, line: int | None, error: str) -> None:
    """A graph file as given; the error is at ``line`` (None: any line)."""
    rel = write(f"graphs/{name}.yaml", content)
    where = r"\d+" if line is None else str(line)
    case(
        f"graph-{name}",
        ["check", rel],
        2,
        rf"^graphs/{name}\.yaml:{where}(:\d+)?: error: .*{error}",
    )


def graphs() -> None:
    reg = "reg: {type: REG_VEL, rate: 100, params: {timeout: 0.1}}"
    jnts = "jnts: {type: WOLVERINE_JNTS, rate: 100, params: {initial_q_deg: [10, 50, -170, 5, 40, 15]}}"
    rates = {
        "rate_inf": (".inf", "must be a positive number"),
        "rate_neg_inf": ("-.inf", "must be a positive number"),
        "rate_nan": (".nan", "must be a positive number"),
        "rate_tiny": ("1.0e-300", "must be from 0.001 to 10000 Hz"),
        "rate_huge": ("1.0e+300", "must be from 0.001 to 10000 Hz"),
        "rate_20khz": ("20000", "must be from 0.001 to 10000 Hz"),
        "rate_zero": ("0", "must be a positive number"),
        "rate_negative": ("-5", "must be a positive number"),
        "rate_text": ("fast", "must be a positive number"),
        "rate_bool": ("true", "must be a positive number"),
        "rate_list": ("[100]", "must be a positive number"),
    }
    for name, (value, error) in rates.items():
        graph_case(
            name,
            {
                "vision: {type: TwistSource, rate: 100": f"vision: {{type: TwistSource, rate: {value}"
            },
            "vision:",
            f"rate.*{error}",
        )
    reg_params = {
        "reg_timeout_inf": ("timeout: .inf", "timeout.*finite number"),
        "reg_timeout_nan": ("timeout: .nan", "timeout.*finite number"),
        "reg_timeout_zero": ("timeout: 0", "timeout.*greater than 0"),
        "reg_timeout_5s": ("timeout: 5", "timeout.*less than or equal to 1"),
        "reg_timeout_text_inf": ("timeout: Infinity", "timeout.*finite number"),
        "reg_timeout_1e999": ("timeout: 1e999", "timeout.*finite number"),
        "reg_max_linear_inf": ("timeout: 0.1, max_linear: .inf", "max_linear.*finite number"),
        "reg_max_linear_1e9": (
            "timeout: 0.1, max_linear: 1.0e9",
            "max_linear.*less than or equal to 1",
        ),
        "reg_max_linear_neg": (
            "timeout: 0.1, max_linear: -0.1",
            "max_linear.*greater than or equal to 0",
        ),
        "reg_max_angular_big": (
            "timeout: 0.1, max_angular: 100",
            "max_angular.*less than or equal to 3.14",
        ),
        "reg_unknown_param": (
            "timeout: 0.1, timout: 0.2",
            "unknown parameter `timout`.*did you mean",
        ),
        "reg_timeout_float_tag": ("timeout: !!float fast", "bad value for tag"),
        "reg_timeout_bool": ("timeout: true", "timeout.*expected a number, found a boolean"),
        "reg_max_linear_yes": (
            "timeout: 0.1, max_linear: yes",
            "max_linear.*expected a number, found a boolean",
        ),
    }
    for name, (params, error) in reg_params.items():
        graph_case(name, {reg: reg.replace("timeout: 0.1", params)}, "reg:", error)
    graph_case(
        "reg_rate_too_slow",
        {reg: reg.replace("rate: 100", "rate: 5")},
        "reg:",
        r"module `reg` \(REG_VEL\): rate 5 Hz is too slow for timeout 0.1 s",
    )
    graph_case(
        "reg_without_rate",
        {reg: "reg: {type: REG_VEL, params: {timeout: 0.1}}"},
        "reg:",
        r"module `reg` \(REG_VEL\): a watchdog needs `rate:`",
    )
    jnts_params = {
        "jnts_command_age_inf": ("max_command_age: .inf, ", "max_command_age.*finite number"),
        "jnts_command_age_10s": (
            "max_command_age: 10, ",
            "max_command_age.*less than or equal to 1",
        ),
        "jnts_accel_inf": ("accel_max: .inf, ", "accel_max.*finite number"),
    }
    for name, (extra, error) in jnts_params.items():
        graph_case(name, {jnts: jnts.replace("params: {", "params: {" + extra)}, "jnts:", error)
    graph_case(
        "jnts_initial_q_short",
        {"[10, 50, -170, 5, 40, 15]": "[10, 50, -170]"},
        "jnts:",
        r"initial_q_deg needs 6 angles, one per joint .*found 3",
    )
    graph_case(
        "jnts_initial_q_nan",
        {"[10, 50, -170, 5, 40, 15]": "[10, 50, .nan, 5, 40, 15]"},
        "jnts:",
        r"initial_q_deg.2.*finite number",
    )
    graph_case(
        "jnts_calibration_error_short",
        {
            "[10, 50, -170, 5, 40, 15]}}": "[10, 50, -170, 5, 40, 15], calibration_error_deg: [1, 2]}}"
        },
        "jnts:",
        r"calibration_error_deg needs 6 angles",
    )
    graph_case(
        "jnts_canopen_without_file",
        {"params: {initial_q_deg": "params: {backend: canopen, initial_q_deg"},
        "jnts:",
        r"canopen_config is needed by backend canopen",
    )
    graph_case(
        "kin_tool_xyz_short",
        {"kin: {type: WOLVERINE_KIN}": "kin: {type: WOLVERINE_KIN, params: {tool_xyz: [0, 0]}}"},
        "kin:",
        r"tool_xyz.*at least 3 items",
    )
    graph_case(
        "kin_tool_rpy_long",
        {
            "kin: {type: WOLVERINE_KIN}": "kin: {type: WOLVERINE_KIN, params: {tool_rpy_deg: [0, 0, 0, 0]}}"
        },
        "kin:",
        r"tool_rpy_deg.*at most 3 items",
    )
    graph_case(
        "kin_state_age_inf",
        {"kin: {type: WOLVERINE_KIN}": "kin: {type: WOLVERINE_KIN, params: {max_state_age: .inf}}"},
        "kin:",
        r"max_state_age.*finite number",
    )
    graph_case(
        "rot_mount_xyz_short",
        {"rot: {type: ROTATE_KIN}": "rot: {type: ROTATE_KIN, params: {mount_xyz: [0, 0]}}"},
        "rot:",
        r"mount_xyz.*at least 3 items",
    )
    graph_case(
        "twist_source_inf",
        {"twist: [0.02, 0, 0, 0, 0, 0.1]": "twist: [.inf, 0, 0, 0, 0, 0.1]"},
        "vision:",
        r"twist.0.*finite number",
    )
    graph_case(
        "dh_file_missing",
        {"params: {initial_q_deg": "params: {dh_file: no_such_dh.yaml, initial_q_deg"},
        "jnts:",
        r"cannot read DH file: no such file",
    )
    for name, target, error in (
        ("dh_file_dev_zero", "/dev/zero", "not a regular file \\(a character device\\)"),
        ("dh_file_bomb", "dh/alias_bomb.yaml", "more than 100000 YAML nodes"),
        ("dh_file_latin1", "dh/latin1.yaml", "not UTF-8 text"),
        ("dh_file_directory", "dh", "is a directory"),
    ):
        graph_case(
            name,
            {
                "params: {initial_q_deg: [10, 50, -170, 5, 40, 15]}": f"params: {{dh_file: {target}}}"
            },
            "jnts:",
            error,
        )
    graph_case(
        "prefix_wildcard",
        {"graph: hostile_arm\n": "graph: hostile_arm\nlinks: {prefix: umbra/*}\n"},
        "links:",
        r"`links.prefix`: .*chunk `\*` may hold only",
    )
    graph_case(
        "prefix_double_star",
        {"graph: hostile_arm\n": "graph: hostile_arm\nlinks: {prefix: '**'}\n"},
        "links:",
        r"`links.prefix`: .*may hold only",
    )
    graph_case(
        "prefix_leading_slash",
        {"graph: hostile_arm\n": "graph: hostile_arm\nlinks: {prefix: /umbra}\n"},
        "links:",
        r"empty chunk",
    )
    graph_case(
        "prefix_empty_chunk",
        {"graph: hostile_arm\n": "graph: hostile_arm\nlinks: {prefix: a//b}\n"},
        "links:",
        r"empty chunk",
    )
    graph_case(
        "prefix_dollar",
        {"graph: hostile_arm\n": "graph: hostile_arm\nlinks: {prefix: 'a/$*b'}\n"},
        "links:",
        r"may hold only",
    )
    graph_case(
        "prefix_too_long",
        {"graph: hostile_arm\n": "graph: hostile_arm\nlinks: {prefix: " + "a" * 300 + "}\n"},
        "links:",
        r"at most 200",
    )
    for name, endpoint, error in (
        ("endpoint_port_too_big", "tcp/127.0.0.1:99999", "port must be a number from 0 to 65535"),
        ("endpoint_unknown_protocol", "foo/127.0.0.1:7447", "unknown protocol `foo`"),
        ("endpoint_no_host", "tcp/:7447", "needs HOST:PORT"),
        ("endpoint_no_protocol", "127.0.0.1:7447", "expected a zenoh endpoint"),
        ("endpoint_bad_host", "tcp/exa mple:7447", "is not an IP address or a host name"),
        ("endpoint_bad_ipv6", "tcp/[::zz]:7447", "is not an IP address"),
        ("endpoint_plain_any", "tcp/0.0.0.0:7447", "reachable beyond this host without TLS"),
        ("endpoint_plain_v6_any", "tcp/[::]:7447", "reachable beyond this host without TLS"),
        ("endpoint_plain_name", "udp/robot.local:7447", "reachable beyond this host without TLS"),
    ):
        graph_case(
            name,
            {"graph: hostile_arm\n": f"graph: hostile_arm\nlinks: {{listen: ['{endpoint}']}}\n"},
            "links:",
            f"`links.listen`: .*{error}",
        )
    write("graphs/bad_zenoh.json5", "{ mode: 'emperor' }\n")
    for name, config, error in (
        ("zenoh_config_missing", "no_such.json5", "no such file"),
        ("zenoh_config_bad", "bad_zenoh.json5", "not a valid zenoh configuration"),
        ("zenoh_config_dev_zero", "/dev/zero", "not a regular file"),
        ("zenoh_config_folder_without_keys", "../dh", "no zenoh configuration for process"),
    ):
        graph_case(
            name,
            {"graph: hostile_arm\n": f"graph: hostile_arm\nlinks: {{zenoh_config: '{config}'}}\n"},
            "links:",
            f"`links.zenoh_config`: .*{error}",
        )
    graph_case(
        "graph_name_space",
        {"graph: hostile_arm": "graph: hostile arm"},
        "graph:",
        "graph name must be an identifier",
    )
    graph_case(
        "graph_name_long",
        {"graph: hostile_arm": "graph: " + "g" * 100},
        "graph:",
        "graph name must be an identifier .* at most 64 characters",
    )
    graph_case(
        "graph_name_number",
        {"graph: hostile_arm": "graph: 5"},
        "graph:",
        "graph name must be an identifier",
    )
    graph_case(
        "graph_name_slash",
        {"graph: hostile_arm": "graph: a/b"},
        "graph:",
        "graph name must be an identifier",
    )
    graph_case(
        "duplicate_module",
        {"  rot: {type: ROTATE_KIN}\n": "  rot: {type: ROTATE_KIN}\n  rot: {type: ROTATE_KIN}\n"},
        "  rot: {type: ROTATE_KIN}\n  kin",
        "duplicate key `rot` \\(first at line 7\\)",
    )
    graph_case(
        "duplicate_param",
        {"timeout: 0.1}": "timeout: 0.1, timeout: .inf}"},
        "reg:",
        "duplicate key `timeout`",
    )
    graph_case(
        "seed_5000_digits",
        {"graph: hostile_arm\n": "graph: hostile_arm\nseed: " + "9" * 5000 + "\n"},
        "seed:",
        "bad value for tag `tag:yaml.org,2002:int`",
    )
    graph_case(
        "python_tag",
        {
            "graph: hostile_arm\n": "graph: hostile_arm\ndescription: !!python/object/apply:os.system [ls]\n"
        },
        "description:",
        "(could not determine a constructor|unsupported YAML tag)",
    )
    graph_case(
        "duration_inf",
        {"graph: hostile_arm\n": "graph: hostile_arm\nduration: .inf\n"},
        "duration:",
        "duration .* must be a positive number",
    )
    graph_case(
        "frame_xyz_nan",
        {"{xyz: [0.0, 0.06, 0.04]": "{xyz: [.nan, 0.06, 0.04]"},
        "tool->camera",
        "`xyz` of frame `tool->camera` must be 3 numbers",
    )
    graph_case(
        "gain_inf",
        {
            "  rot: {type: ROTATE_KIN}\n": "  rot: {type: ROTATE_KIN}\n  g: {type: Gain, rate: 1, params: {gain: .inf}}\n"
        },
        "  g:",
        "gain.*finite number",
    )
    graph_case(
        "printer_rate_nan",
        {
            "  rot: {type: ROTATE_KIN}\n": "  rot: {type: ROTATE_KIN}\n  p: {type: Printer, rate: 1, params: {max_rate_hz: .nan}}\n"
        },
        "  p:",
        "max_rate_hz.*finite number",
    )
    graph_case(
        "unguarded_loop",
        {
            "  vision: {type: TwistSource, rate: 100, params: {twist: [0.02, 0, 0, 0, 0, 0.1]}}\n": "",
            "  - vision.twist -> reg.command\n": "",
            "rot: {type: ROTATE_KIN}": "rot: {type: ROTATE_KIN, params: {mount_xyz: [0, 0, 0], mount_rpy_deg: [0, 0, 0]}}\n"
            "  rot2: {type: ROTATE_KIN, params: {camera_frame: tool, tool_frame: camera, mount_xyz: [0, 0, 0], mount_rpy_deg: [0, 0, 0]}}",
            "  - reg.twist -> rot.camera_twist\n": "  - rot.tool_twist -> rot2.camera_twist\n  - rot2.tool_twist ~> rot.camera_twist\n",
        },
        "  - kin.joint_rates",
        r"must be fed through a safety guard, .* rot -> rot2 -> rot -> kin -> jnts.rates",
    )
    # whole-file problems
    bomb = ["graph: bomb", "a: &a [x, x, x, x, x, x, x, x, x, x]"]
    for i, name in enumerate("bcdefgh"):
        prev = "abcdefgh"[i]
        bomb.append(f"{name}: &{name} [" + ", ".join([f"*{prev}"] * 10) + "]")
    raw_graph("alias_bomb", "\n".join(bomb) + "\n", None, "more than 100000 YAML nodes")
    raw_graph(
        "recursive_alias",
        "graph: r\nmodules: &m {a: *m}\n",
        2,
        "(recursive|nesting deeper than 64)",
    )
    raw_graph(
        "deep_flow",
        "graph: deep\nmodules: " + "[" * 200 + "]" * 200 + "\n",
        2,
        "nesting deeper than 64",
    )
    raw_graph(
        "deep_block",
        "graph: deep\nmodules:\n" + "".join("  " * (i + 1) + "a:\n" for i in range(100)),
        65,
        "nesting deeper than 64",
    )
    raw_graph(
        "latin1",
        "graph: caf\xe9\nmodules: {}\n".encode("latin-1"),
        1,
        r"not UTF-8 text \(byte 10 is 0xe9\)",
    )
    raw_graph("nul_byte", b"graph: a\nmodules:\x00 {}\n", 2, "NUL byte")
    raw_graph("empty", "", 1, "empty graph file")
    raw_graph("top_level_list", "- graph: a\n", 1, "a graph file must be a mapping")
    raw_graph("tab_indent", "graph: a\nmodules:\n\tx: 1\n", 3, "YAML syntax")
    raw_graph(
        "unknown_type",
        "graph: a\nmodules:\n  x: {type: NoSuchModule, rate: 1}\n",
        3,
        "unknown module type `NoSuchModule`",
    )
    raw_graph(
        "seed_negative",
        "graph: a\nseed: -1\nmodules:\n  x: {type: Counter, rate: 1}\n",
        2,
        "seed must be a non-negative integer",
    )
    raw_graph(
        "cpu_latency_huge",
        "graph: a\nprocesses: {main: {cpu_latency_us: 1e99}}\nmodules:\n  x: {type: Counter, process: main, rate: 1}\n",
        2,
        "cpu_latency_us of process `main` must be a whole number",
    )
    raw_graph(
        "binary_tag_key",
        "graph: a\nmodules:\n  ? !!binary aGVsbG8=\n  : {type: Counter, rate: 1}\n",
        3,
        "module name must be an identifier",
    )
    raw_graph(
        "unhashable_key",
        "graph: a\nmodules:\n  ? [1, 2]\n  : {type: Counter, rate: 1}\n",
        3,
        "mapping key must be a plain value",
    )
    chain = [
        "graph: chain",
        "frames:",
        "  tool->camera: {xyz: [0, 0, 0.1]}",
        "modules:",
        "  src: {type: TwistSource, rate: 100}",
    ]
    links, prev = [], "src.twist"
    for i in range(1201):  # deeper than Python's recursion limit: the guard check must not recurse
        frames = "" if i % 2 == 0 else "camera_frame: tool, tool_frame: camera, "
        chain.append(
            f"  r{i}: {{type: ROTATE_KIN, params: {{{frames}mount_xyz: [0, 0, 0], mount_rpy_deg: [0, 0, 0]}}}}"
        )
        links.append(f"  - {prev} -> r{i}.camera_twist")
        prev = f"r{i}.tool_twist"
    chain += [
        "  kin: {type: WOLVERINE_KIN}",
        "  jnts: {type: WOLVERINE_JNTS, rate: 100}",
        "connections:",
        *links,
    ]
    chain += [
        f"  - {prev} -> kin.tool_twist",
        "  - kin.joint_rates -> jnts.rates",
        "  - jnts.joint_state ~> kin.joint_state",
    ]
    raw_graph(
        "long_unguarded_chain",
        "\n".join(chain) + "\n",
        len(chain) - 1,
        r"must be fed through a safety guard, .* -> r3 -> \.\.\. 1194 more \.\.\. -> r1198 ",
    )
    cam = "graph: cam\nmodules:\n  cam: {type: DigiCam, rate: 30, params: {%s}}\n"
    raw_graph(
        "digicam_width_huge",
        cam % "width: 100000, height: 100000",
        3,
        r"width.*less than or equal to 8192",
    )
    raw_graph(
        "digicam_rgb_out_of_range",
        cam % "patch_rgb: [300, 0, 0]",
        3,
        r"parameter .patch_rgb\.0. of .cam.: Input should be less than or equal to 255",
    )
    raw_graph(
        "digicam_patch_size_negative",
        cam % "patch_size_m: [-0.06, 0.04]",
        3,
        r"parameter .patch_size_m\.0. of .cam.: Input should be greater than 0",
    )
    raw_graph(
        "snake_iterations_huge",
        "graph: s\nmodules:\n  s: {type: vsSnake, rate: 30, params: {max_iterations: 1000000000}}\n",
        3,
        r"max_iterations.*less than or equal to 10000",
    )
    raw_graph(
        "yaml_directive_digits",
        "%YAML 1." + "1" * 5000 + "\n---\ngraph: a\n",
        1,
        "YAML syntax: Exceeds the limit",
    )
    raw_graph("merge_of_scalar", "&x <<: *x\n", 1, "bad merge")
    graph_case(
        "rotate_mount_half",
        {"rot: {type: ROTATE_KIN}": "rot: {type: ROTATE_KIN, params: {mount_xyz: [0, 0, 0.1]}}"},
        "rot:",
        "mount_rpy_deg is needed too: give both mount_xyz and mount_rpy_deg, or neither",
    )
    graph_case(
        "rotate_frame_missing",
        {
            "  tool->camera: {xyz: [0.0, 0.06, 0.04], rpy_deg: [0, 0, 90]}\n": "  base->table: {xyz: [0, 0, 0.25]}\n"
        },
        "  rot:",
        r"module `rot` \(ROTATE_KIN\) needs the static frame\(s\) tool->camera",
    )
    graph_case(
        "world_frames_missing",
        {
            "  rot: {type: ROTATE_KIN}\n": "  rot: {type: ROTATE_KIN}\n  world: {type: World, rate: 100}\n"
        },
        "  world:",
        r"module `world` \(World\) needs the static frame\(s\) flange->camera, flange->tool, table->base",
    )
    case("graph-dev-zero", ["check", "/dev/zero"], 2, r"^/dev/zero(:1:1)?: error: ")
    case("graph-directory", ["check", "graphs"], 2, r"^graphs: error: is a directory")
    case("graph-fifo", ["check", "{fifo}"], 2, r"error: .*(not a regular file|FIFO|cannot read)")


def sets() -> None:
    graph = "graphs/set_base.yaml"
    write(graph, ARM_GRAPH)
    for name, item, error in (
        ("timeout_inf", "reg.timeout=.inf", r"^--set reg.timeout: error: .*finite number"),
        ("timeout_1e999", "reg.timeout=1e999", r"^--set reg.timeout: error: .*finite number"),
        ("timeout_Infinity", "reg.timeout=Infinity", r"^--set reg.timeout: error: .*finite number"),
        (
            "timeout_minus_inf",
            "reg.timeout=-Infinity",
            r"^--set reg.timeout: error: .*finite number",
        ),
        ("timeout_nan", "reg.timeout=nan", r"^--set reg.timeout: error: .*finite number"),
        ("timeout_NaN_yaml", "reg.timeout=.NaN", r"^--set reg.timeout: error: .*finite number"),
        ("timeout_zero", "reg.timeout=0", r"^--set reg.timeout: error: .*greater than 0"),
        ("timeout_true", "reg.timeout=true", r"^--set reg.timeout: error: .*found a boolean"),
        (
            "initial_q_bool",
            "jnts.initial_q_deg=[10, 50, -170, 5, 40, false]",
            r"^--set jnts.initial_q_deg: error: .*found a boolean",
        ),
        ("timeout_10s", "reg.timeout=10", r"^--set reg.timeout: error: .*less than or equal to 1"),
        (
            "max_linear_1e9",
            "reg.max_linear=1e9",
            r"^--set reg.max_linear: error: .*less than or equal to 1",
        ),
        (
            "command_age_inf",
            "jnts.max_command_age=.inf",
            r"^--set jnts.max_command_age: error: .*finite",
        ),
        (
            "initial_q_short",
            "jnts.initial_q_deg=[0, 0]",
            r"^--set jnts.initial_q_deg: error: .*needs 6 angles",
        ),
        (
            "tool_xyz_short",
            "kin.tool_xyz=[0, 0]",
            r"^--set kin.tool_xyz: error: .*at least 3 items",
        ),
        ("float_tag", "reg.timeout=!!float abc", r"^--set reg.timeout: error: bad value for tag"),
        ("recursive_alias", "reg.timeout=&a [*a]", r"^--set reg.timeout: error: a recursive alias"),
        (
            "duplicate_key",
            "reg.timeout={a: 1, a: 2}",
            r"^--set reg.timeout: error: duplicate key `a`",
        ),
        (
            "deep",
            "reg.timeout=" + "[" * 100 + "]" * 100,
            r"^--set reg.timeout: error: nesting deeper",
        ),
        (
            "digits_5000",
            "reg.timeout=" + "7" * 5000,
            r"^--set reg.timeout: error: bad value for tag",
        ),
        ("unknown_module", "nosuch.x=1", r"--set: unknown module `nosuch`"),
        (
            "unknown_param",
            "reg.timout=0.2",
            r"^--set reg.timout: error: unknown parameter `timout`",
        ),
        ("no_equals", "reg.timeout", r"--set expects NAME=VALUE"),
        ("no_dot", "timeout=1", r"--set expects MODULE.PARAM=VALUE"),
        ("rate_text", "reg.timeout=fast", r"^--set reg.timeout: error: .*valid number"),
    ):
        case(
            f"set-{name}",
            ["run", graph, "--single-process", "--out", "{tmp}/out", "--set", item],
            2,
            error,
        )
    case(
        "run-prefix-wildcard",
        ["run", graph, "--prefix", "a/*", "--out", "{tmp}/out"],
        2,
        r"^--prefix: error: .*may hold only",
    )
    case(
        "run-listen-bad-port",
        ["run", graph, "--listen", "tcp/127.0.0.1:70000", "--out", "{tmp}/out"],
        2,
        r"^--listen: error: .*port must be",
    )
    case(
        "run-connect-garbage",
        ["run", graph, "--connect", "nonsense", "--out", "{tmp}/out"],
        2,
        r"^--connect: error: expected a zenoh endpoint",
    )
    case(
        "run-duration-negative",
        ["run", graph, "--duration", "-1", "--out", "{tmp}/out"],
        2,
        r"--duration must be a positive, finite number",
    )
    case(
        "run-duration-inf",
        ["run", graph, "--duration", "inf", "--out", "{tmp}/out"],
        2,
        r"--duration must be a positive, finite number .*found inf",
    )


def dh_files() -> None:
    write("dh/ok.yaml", DH_OK)
    bomb = ["name: bomb", "a: &a [x, x, x, x, x, x, x, x, x, x]"]
    for i, name in enumerate("bcdefgh"):
        bomb.append(f"{name}: &{name} [" + ", ".join([f"*{'abcdefgh'[i]}"] * 10) + "]")
    bomb.append("joints: *h")
    cases = {
        "alias_bomb": ("\n".join(bomb) + "\n", None, "more than 100000 YAML nodes"),
        "latin1": (
            "name: Gelenkarm f\xfcr Tests\n".encode("latin-1") + DH_OK.split("\n", 1)[1].encode(),
            1,
            r"not UTF-8 text \(byte \d+ is 0xfc\)",
        ),
        "deep": (
            "name: deep\njoints: " + "[" * 300 + "]" * 300 + "\n",
            2,
            "nesting deeper than 64",
        ),
        "digits_5000": (
            DH_OK.replace("d: 0.3", "d: " + "1" * 5000),
            3,
            "bad value for tag `tag:yaml.org,2002:int`",
        ),
        "float_tag_text": (
            DH_OK.replace("d: 0.3", "d: !!float thirty"),
            3,
            "bad value for tag `tag:yaml.org,2002:float`",
        ),
        "duplicate_key": (
            DH_OK.replace("{name: j1, d: 0.3", "{name: j1, d: 0.3, d: 0.4"),
            3,
            "duplicate key `d`",
        ),
        "duplicate_top": ("name: a\n" + DH_OK, 2, "duplicate key `name`"),
        "recursive": ("name: r\njoints: &j [*j]\n", 2, "recursive alias"),
        "d_inf": (DH_OK.replace("d: 0.3", "d: .inf"), 3, "finite number"),
        "rate_nan": (
            DH_OK.replace("max_rate_deg: 90}\n  - {name: j2", "max_rate_deg: .nan}\n  - {name: j2"),
            3,
            ".",
        ),
        "not_mapping": ("- 1\n- 2\n", 1, "."),
        "empty_joints": ("name: e\njoints: []\n", 2, "."),
        "nul": (b"name: a\x00\n", 1, "NUL byte"),
        "tab": ("name: a\njoints:\n\t- {name: j1}\n", 3, "invalid YAML"),
        "python_tag": (
            "name: !!python/name:os.system x\njoints: []\n",
            1,
            "could not determine a constructor",
        ),
        "utf16_no_bom": ("name: a\n".encode("utf-16-le"), 1, "(not UTF-8 text|NUL byte)"),
    }
    for name, (content, line, error) in cases.items():
        rel = write(f"dh/{name}.yaml", content)
        where = r"\d+" if line is None else str(line)
        case(
            f"dh-{name}",
            ["arm", "--dh", rel, "--q", "0,0"],
            2,
            rf"^dh/{name}\.yaml:{where}: error: .*{error}",
        )
    write("dh/utf8_bom.yaml", b"\xef\xbb\xbf" + DH_OK.encode())
    case("dh-utf8-bom-ok", ["arm", "--dh", "dh/utf8_bom.yaml", "--q", "-0.5,0.25"], 0, "")
    case("dh-negative-q-ok", ["arm", "--dh", "dh/ok.yaml", "--q", "-0.5,-1e-1"], 0, "")
    case(
        "dh-negative-q-count",
        ["arm", "--dh", "dh/ok.yaml", "--q", "-0.5,-1,-2"],
        2,
        r"--q expects 2 finite values",
    )
    case(
        "dh-q-inf", ["arm", "--dh", "dh/ok.yaml", "--q", "inf,0"], 2, r"--q expects 2 finite values"
    )
    case(
        "dh-q-minus-inf",
        ["arm", "--dh", "dh/ok.yaml", "--q", "-inf,0"],
        2,
        r"--q expects 2 finite values",
    )
    case("dh-q-deg-negative-ok", ["arm", "--q-deg", "-30,-10,0,0,-5,0"], 0, "")
    case(
        "dh-dev-zero",
        ["arm", "--dh", "/dev/zero", "--q", "0,0"],
        2,
        r"^/dev/zero: error: not a regular file \(a character device\)",
    )
    case(
        "dh-fifo",
        ["arm", "--dh", "{fifo}", "--q", "0,0"],
        2,
        r"error: not a regular file \(a FIFO\)",
    )
    case("dh-directory", ["arm", "--dh", "dh", "--q", "0,0"], 2, r"^dh: error: is a directory")
    case(
        "dh-missing",
        ["arm", "--dh", "dh/none.yaml", "--q", "0,0"],
        2,
        r"^dh/none\.yaml: error: cannot read DH file: no such file",
    )


def png_header(width: int, height: int) -> bytes:
    """A PNG that claims ``width`` x ``height`` (a decompression bomb's header) with one row."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(b"\x00" * 64))
        + chunk(b"IEND", b"")
    )


def gray_png(width: int, height: int, value: int) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    rows = b"".join(b"\x00" + bytes([value]) * width for _ in range(height))
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(rows))
        + chunk(b"IEND", b"")
    )


def rgb_png(width: int, height: int, rgb: tuple[int, int, int]) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    rows = b"".join(b"\x00" + bytes(rgb) * width for _ in range(height))
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(rows))
        + chunk(b"IEND", b"")
    )


def images() -> None:
    for name, content, error in (
        ("empty", b"", "cannot read it as an image"),
        ("text", b"just some text, no pixels\n", "cannot read it as an image"),
        ("truncated_png", gray_png(64, 64, 128)[:40], "cannot (read|decode) it as an image"),
        ("bomb_png", png_header(100_000, 100_000), r"image is too large to decode"),
        ("tall_png", png_header(1, 9000), r"image is 1x9000 px; at most 8192 px a side"),
        ("wide_png", png_header(40_000, 1), r"image is 40000x1 px"),
        ("zero_png", png_header(0, 0), "cannot (read|decode) it as an image"),
        (
            "jpeg_garbage",
            b"\xff\xd8\xff\xe0" + b"\x00" * 100,
            "cannot (read|decode) it as an image",
        ),
    ):
        rel = write(f"images/{name}.png", content)
        case(
            f"image-{name}",
            ["snake", rel, "--seed", "1,1"],
            2,
            rf"^images/{name}\.png: error: {error}",
        )
    write("images/gray.png", gray_png(160, 120, 128))
    write("images/flat_color.png", rgb_png(160, 120, (40, 160, 60)))
    case(
        "image-grayscale-fails",
        ["snake", "images/gray.png", "--seed", "80,60"],
        1,
        r"(failed|grayscale)",
    )
    case(
        "image-featureless-fails",
        ["snake", "images/flat_color.png", "--seed", "80,60"],
        1,
        r"(failed|border)",
    )
    case(
        "image-seed-negative",
        ["snake", "images/gray.png", "--seed", "-5,3"],
        2,
        r"--seed -5,3 is outside the 160x120 image",
    )
    case(
        "image-seed-nan",
        ["snake", "images/gray.png", "--seed", "nan,3"],
        2,
        r"--seed .*(outside|expects)",
    )
    case(
        "image-dev-zero",
        ["snake", "/dev/zero", "--seed", "1,1"],
        2,
        r"^/dev/zero: error: not a regular file",
    )
    case(
        "image-fifo",
        ["snake", "{fifo}", "--seed", "1,1"],
        2,
        r"error: not a regular file \(a FIFO\)",
    )
    case(
        "image-directory",
        ["snake", "images", "--seed", "1,1"],
        2,
        r"^images: error: is a directory",
    )
    case(
        "image-set-inf",
        ["snake", "images/gray.png", "--seed", "80,60", "--set", "k_sigma=.inf"],
        2,
        r"--set: snake settings: .*should be a finite number",
    )
    case(
        "image-set-iterations-huge",
        ["snake", "images/gray.png", "--seed", "80,60", "--set", "max_iterations=1000000000"],
        2,
        r"--set: snake settings: parameter .max_iterations.: Input should be less than or equal to 10000",
    )
    case(
        "image-set-400-digits",
        ["snake", "images/gray.png", "--seed", "80,60", "--set", "max_iterations=" + "9" * 400],
        2,
        r"--set: snake settings: parameter .max_iterations.: Input should be less than or equal to 10000, found 9{20}",
    )


ZOOM_XML_OK = """<?xml version="1.0"?>
<SR_world>
<SR_cam> zcam
<SR_zoom> 0.0
<SR_cam_int> {740.0 741.6 -4.58 344.25 212.84 0 0 0 0} </SR_cam_int>
<SR_cam_ext> {-0.004 0.041 0.006 0.009 -0.004 0.034} </SR_cam_ext>
</SR_zoom>
<SR_zoom> 1.0
<SR_cam_int> {7400.0 7416 -4.58 344.25 212.84 0 0 0 0} </SR_cam_int>
<SR_cam_ext> {-0.004 0.041 0.006 0.009 -0.004 0.034} </SR_cam_ext>
</SR_zoom>
</SR_cam>
</SR_world>
"""


def calibration() -> None:
    write("calib/zoom_ok.xml", ZOOM_XML_OK)
    laughs = '<?xml version="1.0"?>\n<!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">]>\n<SR_world>&lol2;</SR_world>\n'
    xml_cases = {
        "billion_laughs": (laughs, 2, "DOCTYPE declarations are not allowed"),
        "external_entity": (
            '<?xml version="1.0"?>\n<!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]>\n<SR_world>&e;</SR_world>\n',
            2,
            "DOCTYPE declarations are not allowed",
        ),
        "not_well_formed": (
            ZOOM_XML_OK.replace(
                "</SR_cam_ext>\n</SR_zoom>\n<SR_zoom> 1.0", "</SR_cam_ext>\n<SR_zoom> 1.0", 1
            ),
            11,
            "not well-formed XML|mismatched tag",
        ),
        "inf_value": (
            ZOOM_XML_OK.replace("{740.0 741.6", "{inf 741.6"),
            5,
            r"bad number 'inf'.*must be finite",
        ),
        "nan_value": (
            ZOOM_XML_OK.replace("{740.0 741.6", "{nan 741.6"),
            5,
            r"bad number 'nan'.*must be finite",
        ),
        "digits_5000": (
            ZOOM_XML_OK.replace("{740.0 741.6", "{" + "9" * 5000 + " 741.6"),
            5,
            r"must be finite",
        ),
        "no_braces": (
            ZOOM_XML_OK.replace(
                "{740.0 741.6 -4.58 344.25 212.84 0 0 0 0}",
                "740.0 741.6 -4.58 344.25 212.84 0 0 0 0",
            ),
            5,
            "must be enclosed in braces",
        ),
        "too_few": (
            ZOOM_XML_OK.replace("{740.0 741.6 -4.58 344.25 212.84 0 0 0 0}", "{740.0 741.6}"),
            5,
            "needs 9 values",
        ),
        "zoom_outside": (
            ZOOM_XML_OK.replace("<SR_zoom> 1.0", "<SR_zoom> 7"),
            8,
            "outside the normalized range",
        ),
        "zoom_decreasing": (
            ZOOM_XML_OK.replace("<SR_zoom> 1.0", "<SR_zoom> 0.0"),
            8,
            "does not increase",
        ),
        "deep": (
            '<?xml version="1.0"?>\n<SR_world>\n' + "<a>" * 500 + "</a>" * 500 + "\n</SR_world>\n",
            3,
            "unexpected element <a>",
        ),
        "latin1_undeclared": (
            ZOOM_XML_OK.replace("zcam", "kam\xe9ra").encode("latin-1"),
            3,
            "not well-formed XML",
        ),
        "junk_after_root": (ZOOM_XML_OK + "<SR_world/>\n", 14, "junk after document element"),
        "empty": ("", 1, "not well-formed XML|no element found"),
        "negative_focal": (
            ZOOM_XML_OK.replace("{740.0 741.6", "{-740.0 741.6"),
            5,
            "focal lengths must be positive",
        ),
    }
    for name, (content, line, error) in xml_cases.items():
        rel = write(f"calib/{name}.xml", content)
        case(
            f"zoom-xml-{name}",
            ["calib", "zoom", rel, "--at", "0.5"],
            2,
            rf"^calib/{name}\.xml:{line}: error: .*({error})",
        )
    write(
        "calib/latin1_declared.xml",
        ZOOM_XML_OK.replace('<?xml version="1.0"?>', '<?xml version="1.0" encoding="ISO-8859-1"?>')
        .replace("zcam", "kam\xe9ra")
        .encode("latin-1"),
    )
    case(
        "zoom-xml-latin1-declared-ok",
        ["calib", "zoom", "calib/latin1_declared.xml", "--at", "0.5"],
        0,
        "",
    )
    case(
        "zoom-xml-dev-zero",
        ["calib", "zoom", "/dev/zero.xml", "--at", "0.5"],
        2,
        r"error: cannot read zoom calibration file: no such file",
    )
    case(
        "zoom-at-negative",
        ["calib", "zoom", "calib/zoom_ok.xml", "--at", "-0.5"],
        2,
        r"(0\.\.1|normalized)",
    )
    zoom_yaml = (HERE.parent.parent.parent / "modules/calib/data/zoom_cam.yaml").read_text()
    yaml_cases = {
        "duplicate_key": (
            zoom_yaml.replace("fx: 740.09,", "fx: 740.09, fx: 1,", 1),
            10,
            "duplicate key `fx`",
        ),
        "float_tag": (
            zoom_yaml.replace("fx: 740.09", "fx: !!float wide", 1),
            10,
            "(bad number 'wide'|bad value for tag)",
        ),
        "deep": ("cameras: " + "[" * 200 + "]" * 200 + "\n", 1, "nesting deeper than 64"),
        "alias_bomb": (
            "a: &a [x, x, x, x, x, x, x, x, x, x]\n"
            + "".join(
                f"{n}: &{n} [" + ", ".join([f"*{p}"] * 10) + "]\n"
                for p, n in zip("abcdefg", "bcdefgh", strict=True)
            )
            + "cameras: *h\n",
            r"\d+",
            "more than 100000 YAML nodes",
        ),
        "inf": (
            zoom_yaml.replace("fx: 740.09", "fx: .inf", 1),
            10,
            "(bad number '.inf'|must be finite)",
        ),
    }
    for name, (content, line, error) in yaml_cases.items():
        rel = write(f"calib/zoom_{name}.yaml", content)
        case(
            f"zoom-yaml-{name}",
            ["calib", "zoom", rel, "--at", "0.5"],
            2,
            rf"^calib/zoom_{name}\.yaml:{line}: error: .*{error}",
        )
    cams_ok = "cameras:\n  left:\n    intrinsics: {fx: 800, fy: 800, skew: 0, u0: 320, v0: 240}\n    pose: {xyz: [0.0, 0.0, 0.0], rpy_deg: [0, 0, 0]}\n  right:\n    intrinsics: {fx: 800, fy: 800, skew: 0, u0: 320, v0: 240}\n    pose: {xyz: [0.2, 0.0, 0.0], rpy_deg: [0, 0, 0]}\n"
    write("calib/cams_ok.yaml", cams_ok)
    cam_cases = {
        "duplicate_camera": (cams_ok.replace("  right:", "  left:"), 5, "duplicate"),
        "nan_pose": (
            cams_ok.replace("xyz: [0.2, 0.0, 0.0]", "xyz: [.nan, 0.0, 0.0]"),
            7,
            "(bad number '.nan'|must be finite)",
        ),
        "zoom_file_dev_zero": (
            "cameras:\n  z: {zoom_file: /dev/zero, zoom: 0.5, mount_pose: {xyz: [0, 0, 0]}}\n",
            1,
            "",
        ),
        "bomb": (
            "a: &a [x, x, x, x, x, x, x, x, x, x]\n"
            + "".join(
                f"{n}: &{n} [" + ", ".join([f"*{p}"] * 10) + "]\n"
                for p, n in zip("abcdefg", "bcdefgh", strict=True)
            )
            + "cameras: *h\n",
            r"\d+",
            "more than 100000 YAML nodes",
        ),
    }
    for name, (content, line, error) in cam_cases.items():
        rel = write(f"calib/cams_{name}.yaml", content)
        pattern = (
            rf"^calib/cams_{name}\.yaml:{line}: error: .*{error}"
            if error
            else r"^/dev/zero: error: "
        )
        case(
            f"cameras-{name}",
            ["calib", "triangulate", rel, "--pixel", "left=320,240", "--pixel", "right=160,240"],
            2,
            pattern,
        )
    case(
        "triangulate-negative-pixel",
        [
            "calib",
            "triangulate",
            "calib/cams_ok.yaml",
            "--pixel",
            "left=-20,240",
            "--pixel",
            "right=-180,240",
        ],
        0,
        "",
    )
    header = "x,y,z,u,v\n"
    good_rows = "".join(
        f"{0.1 * (i % 3)},{0.1 * (i // 3 % 3)},{0.05 * (i // 9)},{100 + 10 * i},{50 + 7 * i}\n"
        for i in range(20)
    )
    csv_cases = {
        "bad_header": ("a,b,c\n1,2,3\n", 1, "header must name the columns"),
        "nan": (header + "0,0,nan,1,2\n", 2, "z must be finite"),
        "inf": (header + "0,0,0,inf,2\n", 2, "u must be finite"),
        "text": (header + "0,0,zero,1,2\n", 2, "bad number 'zero' in column z"),
        "short_row": (header + "0,0,0,1\n", 2, "expected 5 values, found 4"),
        "huge_field": (header + "0,0,0,1," + "9" * 200_000 + "\n", 2, "(not a CSV line|finite)"),
        "nul": (header.encode() + b"0,0,0\x00,1,2\n", 2, "NUL byte"),
        "latin1": ("x,y,z,u,v # \xe9\n".encode("latin-1"), 1, "not UTF-8 text"),
        "empty": ("", 1, "no header"),
        "header_only": (header, 1, "no correspondences after the header"),
        "unclosed_quote": (header + '0,0,0,"1,2\n', 2, "(expected 5 values|bad number)"),
        "coplanar": (
            header + "".join(f"{0.1 * i},{0.02 * i * i},0,{100 + i},{50 + i}\n" for i in range(12)),
            None,
            "coplanar",
        ),
    }
    for name, (content, line, error) in csv_cases.items():
        rel = write(f"calib/pairs_{name}.csv", content)
        pattern = rf"^calib/pairs_{name}\.csv:{line}: error: .*{error}" if line else error
        case(f"csv-{name}", ["calib", "fit", rel], 2, pattern)
    write("calib/pairs_ok.csv", header + good_rows)
    case(
        "fit-output-missing-folder",
        ["calib", "fit", "calib/pairs_ok.csv", "-o", "{tmp}/no/such/folder/cam.yaml"],
        2,
        r"--output .*: error: folder .* does not exist",
    )
    case(
        "fit-output-is-folder",
        ["calib", "fit", "calib/pairs_ok.csv", "-o", "{tmp}"],
        2,
        r"--output .*: error: is a folder",
    )
    case(
        "fit-zoom-negative",
        ["calib", "fit", "calib/pairs_ok.csv", "--zoom", "-0.1"],
        2,
        r"--zoom must be a normalized zoom in 0\.\.1, got -0\.1",
    )
    pose_header = "camera,x,y,z,u,v\n"
    collinear = pose_header + "".join(
        f"left,{0.01 * i},{0.005 * i},0,{320 + 8 * i},{240 + 4 * i}\n" for i in range(8)
    )
    coincident = pose_header + "left,0,0,0,320,240\n" * 6
    write("calib/pose_collinear.csv", collinear)
    write("calib/pose_coincident.csv", coincident)
    write("calib/pose_unknown_camera.csv", pose_header + "middle,0,0,0,320,240\n")
    case(
        "pose-collinear",
        ["calib", "pose", "calib/pose_collinear.csv", "--cameras", "calib/cams_ok.yaml"],
        2,
        r"lie on one line",
    )
    case(
        "pose-coincident",
        ["calib", "pose", "calib/pose_coincident.csv", "--cameras", "calib/cams_ok.yaml"],
        2,
        r"at one place",
    )
    case(
        "pose-unknown-camera",
        ["calib", "pose", "calib/pose_unknown_camera.csv", "--cameras", "calib/cams_ok.yaml"],
        2,
        r"^calib/pose_unknown_camera\.csv:2: error: unknown camera 'middle'",
    )


def issue29() -> None:
    """Issue #29's files and inputs: hand-edited sketch sessions, pose-tool sessions and options,
    damaged recordings (no bombs: the tests write those), and parameters check must refuse."""
    import sys

    sys.path.insert(0, str(HERE.parents[2]))
    import numpy as np

    from tests.hostile.bombs import MAGIC, chunk_payload, crc, mcap_bytes
    from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
    from umbra.modules.calib.pose_tool_file import session_text

    ok_event = '{"cmd": "aim", "xyz": [0.5, 0, 0.3], "at": null, "zoom": 0.2}'
    sessions = {
        "latin1": (
            b'{"seed": 3,\n "events": [{"cmd": "aim", "at": "caf\xe9"}]}',
            2,
            "not UTF-8 text",
        ),
        "deep": (
            b'{"seed": 3, "events": ' + b"[" * 50_000 + b"]" * 50_000 + b"}",
            None,
            "Expected `object`, got `array`",
        ),
        "seed_type": (
            b'{"seed": "3", "events": []}',
            None,
            "Expected `int`, got `str` - at `\\$.seed`",
        ),
        "events_shape": (
            b'{"seed": 3, "events": {"0": {"cmd": "snapshot"}}}',
            None,
            "Expected `array`, got `object` - at `\\$.events`",
        ),
        "unknown_command": (
            b'{"seed": 3, "events": [{"cmd": "launch"}]}',
            None,
            "unknown value 'launch' \\(expected one of aim, ",
        ),
        "missing_keys": (
            b'{"seed": 3, "events": [{"cmd": "aim", "xyz": [1, 2, 3]}]}',
            None,
            "Object missing required field `at`",
        ),
        "missing_events": (b'{"seed": 3}', None, "Object missing required field `events`"),
        "unknown_key": (
            f'{{"seed": 3, "events": [{ok_event[:-1]}, "x": 1}}]}}'.encode(),
            None,
            "Object contains unknown field `x`",
        ),
        "nan": (
            b'{"seed": 3,\n"events": [{"cmd": "aim", "xyz": [NaN, 0, 0], "at": null, "zoom": null}]}',
            2,
            "JSON is malformed",
        ),
        "script_step": (
            b'{"seed": 3, "events": [{"cmd": "play", "path": "p", "script": [[0, "play"]], "timeout": 9}]}',
            None,
            "Expected `array` of length 3",
        ),
    }
    for name, (content, line, error) in sessions.items():
        write(f"sketch/{name}/session.json", content)
        where = r"(:\d+)?" if line is None else f":{line}"
        case(
            f"sketch-{name}",
            ["sketch", "macros", f"sketch/{name}"],
            2,
            rf"^sketch/{name}/session\.json{where}: error: {error}",
        )

    camera = PinholeCamera(Intrinsics(800.0, 800.0, 0.0, 320.0, 240.0))
    square = {
        "a": np.array([0.0, 0.0, 0.5]),
        "b": np.array([0.1, 0.0, 0.5]),
        "c": np.array([0.0, 0.1, 0.5]),
        "d": np.array([0.1, 0.1, 0.6]),
    }
    clicks = {k: (320.0 + 800 * p[0] / p[2], 240.0 + 800 * p[1] / p[2]) for k, p in square.items()}
    ok = session_text("ptu_head", "camera", camera, square, [(np.eye(4), np.eye(4), clicks)])
    write("posetool/ok.yaml", ok)
    for value in ("nan", "inf", "-1", "0"):
        case(
            f"posetool-max_rms_{value.replace('-', 'minus')}",
            ["pose-tool", "posetool/ok.yaml", f"--max-rms-px={value}", "-o", "{tmp}/mount.yaml"],
            2,
            "--max-rms-px: expected a finite number of pixels > 0",
        )
    one = session_text(
        "ptu_head",
        "camera",
        camera,
        {"a": square["a"]},
        [(np.eye(4), np.eye(4), {"a": clicks["a"]})] * 6,
    )
    write("posetool/one_point.yaml", one)
    case(
        "posetool-one_point",
        ["pose-tool", "posetool/one_point.yaml"],
        2,
        r"^posetool/one_point\.yaml:\d+: error: all 6 clicks are on one point",
    )
    line = {f"p{i}": np.array([0.05 * i, 0.0, 0.5]) for i in range(4)}
    write(
        "posetool/collinear.yaml",
        session_text(
            "ptu_head",
            "camera",
            camera,
            line,
            [
                (
                    np.eye(4),
                    np.eye(4),
                    {k: (320.0 + 800 * p[0] / 0.5, 240.0) for k, p in line.items()},
                )
            ],
        ),
    )
    case(
        "posetool-collinear",
        ["pose-tool", "posetool/collinear.yaml"],
        2,
        r"^posetool/collinear\.yaml:\d+: error: the 4 clicked points lie on one line",
    )
    for name, mount in {
        "mount_space": "ptu head->camera",
        "mount_yaml": "'&a x->camera'",
        "mount_twice": "camera->camera",
        "mount_chain": "a->b->c",
    }.items():
        write(f"posetool/{name}.yaml", ok.replace("mount: ptu_head->camera", f"mount: {mount}"))
        case(
            f"posetool-{name}",
            ["pose-tool", f"posetool/{name}.yaml", "-o", "{tmp}/mount.yaml"],
            2,
            rf"^posetool/{name}\.yaml:2: error: mount ",
        )

    payload = chunk_payload(3)
    good = mcap_bytes("", payload, len(payload), crc=crc(payload))
    head_end = len(MAGIC) + 9 + int.from_bytes(good[len(MAGIC) + 1 : len(MAGIC) + 9], "little")
    recordings = {
        "long_record": (
            good[:head_end] + b"\x03" + (2**40).to_bytes(8, "little") + bytes(64),
            "corrupted: the record at byte \\d+ of \\d+ claims 1099511627776 bytes, more than the \\d+ a recording's record may hold",
        ),
        "past_the_end": (
            good[:head_end] + b"\x03" + (10_000).to_bytes(8, "little") + bytes(64),
            "truncated: the file ends inside a record",
        ),
        "stored_lying": (
            mcap_bytes("", bytes(20_000), 5000),
            "a chunk \\(stored\\) declares 5000 bytes uncompressed but holds more than that",
        ),
        "chunk_too_big": (
            mcap_bytes("zstd", b"\x28\xb5\x2f\xfd", 2**40),
            "a chunk declares 1099511627776 bytes uncompressed, more than the",
        ),
        "unknown_compression": (
            mcap_bytes("bz2", payload, len(payload)),
            "unknown chunk compression 'bz2'",
        ),
        "bad_crc": (
            mcap_bytes("", payload, len(payload), crc=crc(payload) ^ 1),
            "fails its checksum",
        ),
    }
    for name, (content, error) in recordings.items():
        write(f"record/{name}.mcap", content)
        case(
            f"record-{name}",
            ["record-info", f"record/{name}.mcap"],
            2,
            rf"^record/{name}\.mcap: error: .*{error}",
        )

    raw_graph(
        "sony_port_yaml",
        "graph: g\nmodules:\n  sony: {type: SONY, rate: 20, params: {port: '&a x'}}\n",
        3,
        "port '&a x' is not a serial device",
    )
    raw_graph(
        "sony_port_relative",
        "graph: g\nmodules:\n  sony: {type: SONY, rate: 20, params: {port: ttyUSB0}}\n",
        3,
        "is not a serial device",
    )
    script = "graph: g\nmodules:\n  op:\n    type: SketchOperatorSim\n    params:\n      script:\n        - snapshot\n        - {step}\n"
    for name, step, error in [
        ("script_not_a_command", "rm -rf /", "script step 2 'rm -rf /': not a command"),
        ("script_wait_word", "wait soon", "expected `wait S`"),
        ("script_vcr", "vcr fly", "expected vcr ACTION"),
    ]:
        raw_graph(name, script.format(step=repr(step)), None, error)


def loader_exact() -> None:
    """Issue 40: positions whatever the whitespace, YAML 1.1 merge keys, files a graph writes
    inside the run folder (outside only when named on the command line), graphs that extend."""
    base = "graph: g\nmodules:\n  a: {type: Counter, rate: 10}\n  b:\n    type: Printer\n    trigger: value\nconnections:\n  - a.count -> b.value\n"
    odd = {
        "nbsp": "\u00a0",
        "em_space": "\u2003",
        "ideographic_space": "\u3000",
        "zero_width_space": "\u200b",
        "narrow_nbsp": "\u202f",
        "tab": "\t",
    }
    for name, char in odd.items():
        text = base.replace("    type: Printer", char + "   type: Printer")
        raw_graph(
            f"indent_{name}", text, 5, rf"\(U\+{ord(char):04X}\) where YAML expects indentation"
        )
        raw_graph(
            f"indent_{name}_crlf",
            text.replace("\n", "\r\n").encode(),
            5,
            "where YAML expects indentation",
        )
    deeper = write(
        "graphs/indent_nbsp_deeper.yaml",
        base.replace("    trigger: value", "  \u00a0 trigger: value"),
    )
    case(
        "graph-indent_nbsp_deeper",
        ["check", deeper],
        2,
        r"^graphs/indent_nbsp_deeper\.yaml:6:3: error: .*no-break space \(U\+00A0\)",
    )
    raw_graph(
        "crlf_bad_rate",
        base.replace("rate: 10", "rate: -10").replace("\n", "\r\n").encode(),
        3,
        "rate.*must be a positive number",
    )
    raw_graph(
        "bom_crlf_bad_rate",
        b"\xef\xbb\xbf" + base.replace("rate: 10", "rate: -10").replace("\n", "\r\n").encode(),
        3,
        "rate.*must be a positive number",
    )
    for name, end in (
        ("line_separator", "\u2028"),
        ("paragraph_separator", "\u2029"),
        ("next_line", "\x85"),
        ("lone_cr", "\r"),
    ):
        raw_graph(
            name,
            base.replace("{type: Counter, rate: 10}", "{type: Counter," + end + " rate: 10}"),
            3,
            r"ends a line here.*LF or CRLF",
        )
    merged = "graph: g\nvalues: {base: &base {type: Counter, rate: 10, params: {start: 1}}}\nmodules:\n  a: {<<: *base, rate: 20}\n  b: {type: Printer, trigger: value}\nconnections:\n  - a.count -> b.value\n"
    for name, text in (
        ("merge_override", merged),
        (
            "merge_sibling_anchor",
            "graph: g\nmodules:\n  a: &base {type: Counter, rate: 10}\n  c:\n    <<: *base\n    rate: 20\n  b: {type: Printer, trigger: value}\n  d: {type: Printer, trigger: value}\nconnections:\n  - a.count -> b.value\n  - c.count -> d.value\n",
        ),
        ("merge_list", merged.replace("<<: *base", "<<: [{rate: 5}, *base]")),
    ):
        write(f"graphs/{name}.yaml", text)
        case(f"graph-{name}", ["check", f"graphs/{name}.yaml"], 0, "")
    raw_graph(
        "merge_own_key_twice",
        merged.replace("rate: 20}", "rate: 20, rate: 30}"),
        4,
        "duplicate key `rate`",
    )
    raw_graph(
        "merge_scalar", merged.replace("<<: *base", "<<: 5"), 4, "bad merge: `<<` takes a mapping"
    )
    raw_graph(
        "merge_key_twice", merged.replace("rate: 20}", "<<: *base}"), 4, "duplicate merge key `<<`"
    )
    rec = "graph: g\nmodules:\n  src: {type: Counter, rate: 10}\n  rec: {type: Recorder, params: {channels: [count], path: %s}}\nconnections:\n  - src.count -> rec.count\n"
    for name, path, error in (
        (
            "recorder_absolute",
            "/tmp/evil.mcap",
            r"path '/tmp/evil\.mcap' is absolute.*--set MODULE\.PARAM=PATH",
        ),
        ("recorder_home", "/root/.bashrc", "is absolute"),
        ("recorder_dotdot", "../evil.mcap", r"leaves the run folder \(`\.\.`\)"),
        ("recorder_deep_dotdot", "a/b/../../../evil.mcap", "leaves the run folder"),
        ("recorder_backslash_dotdot", "'..\\evil.mcap'", "leaves the run folder"),
        ("recorder_windows_drive", "'C:/evil.mcap'", "is absolute"),
        ("recorder_unc", "'//server/share/evil.mcap'", "is absolute"),
        ("recorder_empty", "''", "path"),
    ):
        raw_graph(name, rec % path, 4, error)
    for name, text, error in (
        (
            "overlay_video_absolute",
            "graph: g\nmodules:\n  view: {type: Overlay, params: {video: /tmp/evil.avi}}\n",
            "is absolute",
        ),
        (
            "plot_path_dotdot",
            "graph: g\nmodules:\n  plot: {type: StatusPlot, params: {keys: [a], path: ../evil.png}}\n",
            "leaves the run folder",
        ),
        (
            "view3d_scene_absolute",
            "graph: g\nmodules:\n  v: {type: View3D, rate: 10, params: {scene_file: /tmp/evil.json}}\n",
            "is absolute",
        ),
        (
            "record_file_dotdot",
            "graph: g\nrecord: {file: ../evil.mcap}\nmodules:\n  src: {type: Counter, rate: 10}\n",
            "leaves the run folder",
        ),
    ):
        raw_graph(name, text, 3 if "record:" not in text else 2, error)
    write("graphs/recorder_inside.yaml", rec % "rec.mcap")
    for name, path in (("absolute", "{tmp}/elsewhere/rec.mcap"), ("dotdot", "../beside.mcap")):
        case(
            f"run-recorder_{name}_on_command_line",
            [
                "run",
                "graphs/recorder_inside.yaml",
                "--single-process",
                "--clock",
                "sim",
                "--duration",
                "0.2",
                "--quiet",
                "--out",
                "{tmp}/out",
                "--set",
                f"rec.path={path}",
            ],
            0,
            "",
        )
    raw_graph(
        "extends_missing",
        "extends: no_such_base.yaml\ngraph: g\n",
        1,
        r"`extends`: no such graph file `graphs/no_such_base\.yaml`",
    )
    raw_graph(
        "extends_dev_zero", "graph: g\nextends: /dev/zero\n", 2, r"`extends`: .*not a regular file"
    )
    raw_graph("extends_list", "graph: g\nextends: [a.yaml]\n", 2, r"`extends` names the graph file")
    write("graphs/extends_cycle_b.yaml", "graph: b\nextends: extends_cycle_a.yaml\n")
    cycle = write("graphs/extends_cycle_a.yaml", "graph: a\nextends: extends_cycle_b.yaml\n")
    case(
        "graph-extends_cycle",
        ["check", cycle],
        2,
        r"^graphs/extends_cycle_b\.yaml:2:10: error: `extends: extends_cycle_a\.yaml` makes a cycle: extends_cycle_a\.yaml -> extends_cycle_b\.yaml -> extends_cycle_a\.yaml",
    )
    write("graphs/extends_bad_base.yaml", base.replace("rate: 10", "rate: .inf"))
    write(
        "graphs/extends_child.yaml",
        "extends: extends_bad_base.yaml\ngraph: child\nmodules:\n  b: {trigger: nope}\n",
    )
    case(
        "graph-extends_error_in_base",
        ["check", "graphs/extends_child.yaml"],
        2,
        r"^graphs/extends_bad_base\.yaml:3(:\d+)?: error: .*rate.*must be a positive number",
    )
    case(
        "graph-extends_error_in_child",
        ["check", "graphs/extends_child.yaml"],
        2,
        r"^graphs/extends_child\.yaml:4(:\d+)?: error: .*`trigger` names `nope`",
    )
    raw_graph(
        "remove_connection_unknown",
        "extends: extends_bad_base.yaml\ngraph: c\nremove_connections:\n  - a.count -> b.nope\n",
        4,
        r"has no connection `a\.count -> b\.nope`",
    )
    raw_graph(
        "value_unknown",
        "graph: g\nvalues: {hz: 10}\nmodules:\n  a: {type: Counter, rate: $hzz}\n",
        4,
        r"`\$hzz` names no value of `values:`.*did you mean",
    )


def main() -> None:
    graphs()
    sets()
    dh_files()
    images()
    calibration()
    issue29()
    loader_exact()
    ids = [c["id"] for c in CASES]
    assert len(ids) == len(set(ids)), "duplicate case ids"
    lines = [
        "# Hostile inputs: each case runs `umbra ARGV` in this folder ({tmp}: a fresh folder,",
        "# {fifo}: a named pipe, {repo}: the checkout) and expects `status` and a stderr line",
        "# matching the regular expression `error` (empty: any). Written by ../make_corpus.py.",
        "cases:",
    ]
    for c in CASES:
        lines.append(f"  - id: {c['id']}")
        lines.append(f"    argv: {json.dumps(c['argv'])}")
        lines.append(f"    status: {c['status']}")
        lines.append(f"    error: {json.dumps(c['error'])}")
    (HERE / "manifest.yaml").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"{len(CASES)} cases")


if __name__ == "__main__":
    main()
