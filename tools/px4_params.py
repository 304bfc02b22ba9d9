#!/usr/bin/env python3
"""Extract the parameters PX4 SITL's default multicopter boots with into params/px4-multicopter.tsv.

Reads a PX4-Autopilot git repository at one commit (facts only: names,
types, defaults, ranges, units, short descriptions) and writes one line per
parameter:

    name  type  default  min  max  unit  description  source

`type` is INT32 or FLOAT; `min`/`max` are empty where PX4 declares no bound;
`default` is the value the vehicle boots with: the module default, then the
`param set-default` / `param set` lines of the SITL startup scripts in the
order PX4 runs them (posix rcS, the gz_x500 airframe 4001_gz_x500 and the
rc.mc_defaults it sources, px4-rc.simulator). `source` is the file that
declares the parameter, or `<file> (default: <script>)` when a startup
script changed its default.

Which parameters: those of the modules that the board config
boards/px4/sitl/default.px4board builds AND the multicopter SITL boot starts
(STARTED below, read from the startup scripts), plus the libraries they link
(LIBS); fixed-wing, rover, VTOL, UUV, airship and spacecraft modules, the
alternative estimators that are not started (LPE, attitude_estimator_q) and
hardware drivers not run in SITL are left out, as are the serial-port
`*_CONFIG` parameters (SITL has no serial ports). PX4 sends over MAVLink only
the parameters its running modules use; this rule approximates that set from
the sources.

Usage (stdlib + PyYAML):
    python3 tools/px4_params.py --git-dir PX4-Autopilot/.git --commit <sha> > params/px4-multicopter.tsv
"""

import argparse
import re
import subprocess
import sys

import yaml

# Modules the multicopter SITL boot starts (posix rcS, rc.mc_apps, px4-rc.gzsim,
# px4-rc.simulator), by directory under src/modules/. Conditional starts are
# listed when their condition holds at the SITL defaults (MC_AT_EN 1,
# IMU_GYRO_FFT_EN 1, IMU_GYRO_CAL_EN 1, SIM_BAT_ENABLE 1, EKF2_EN 1).
STARTED = [
    "dataman",
    "load_mon",
    "simulation/battery_simulator",
    "simulation/gz_bridge",
    "simulation/pwm_out_sim",
    "rc_update",
    "manual_control",
    "sensors",
    "commander",
    "ekf2",
    "control_allocator",
    "mc_rate_control",
    "mc_att_control",
    "mc_autotune_attitude_control",
    "mc_hover_thrust_estimator",
    "flight_mode_manager",
    "mc_pos_control",
    "land_detector",
    "navigator",
    "uxrce_dds_client",
    "gyro_fft",
    "gyro_calibration",
    "payload_deliverer",
    "mavlink",
    "logger",
]

# Libraries linked into the started modules whose parameters PX4 declares.
LIBS = [
    "systemlib",
    "battery",
    "circuit_breaker",
    "collision_prevention",
    "weather_vane",
    "mixer_module",
    "led",
]

# Files in those directories that are not part of the SITL multicopter build.
SKIP_FILES = [
    "src/modules/simulation/pwm_out_sim/module_hil.yaml",
    "src/modules/land_detector/land_detector_params_fw.c",
    "src/modules/navigator/vtol_takeoff_params.c",
]

# The startup scripts, in the order PX4 SITL runs them for gz_x500 (instance 0).
SCRIPTS = [
    "ROMFS/px4fmu_common/init.d-posix/rcS",
]
SOURCED = {
    '"$autostart_file"': "ROMFS/px4fmu_common/init.d-posix/airframes/4001_gz_x500",
    "${R}etc/init.d/rc.mc_defaults": "ROMFS/px4fmu_common/init.d/rc.mc_defaults",
    "px4-rc.simulator": "ROMFS/px4fmu_common/init.d-posix/px4-rc.simulator",
}
# `param set` lines whose value is a shell expression, as they evaluate for instance 0.
SHELL_VALUES = {"MAV_SYS_ID": "1", "UXRCE_DDS_KEY": "1", "SYS_AUTOSTART": "4001"}
# Set by the script only to trigger a reset, not a value the vehicle keeps.
TRANSIENT = {"SYS_AUTOCONFIG"}


def git(args, git_dir):
    return subprocess.run(["git", "--git-dir", git_dir, *args], check=True, capture_output=True).stdout


def show(git_dir, commit, path):
    return git(["show", f"{commit}:{path}"], git_dir).decode("utf-8", "replace")


def board_modules(text):
    """Directories (under src/modules) the board config enables."""
    out = set()
    for m in re.finditer(r"^CONFIG_MODULES_([A-Z0-9_]+)=y", text, re.M):
        out.add(m.group(1).lower())
    if re.search(r"^CONFIG_COMMON_SIMULATION=y", text, re.M):
        out.add("simulation")
    return out


def number(text):
    t = text.strip().rstrip("fF")
    t = re.sub(r"(\d)[uUlL]+$", r"\1", t)
    if re.fullmatch(r"[-+]?(0x[0-9a-fA-F]+|\d+)", t):
        return int(t, 0)
    if re.fullmatch(r"[-+0-9.eE]+", t):
        return float(t)
    if re.fullmatch(r"[-+*/()<>|&0-9.xXa-fA-F eE]+", t):
        return eval(t, {"__builtins__": {}})  # a constant expression of literals
    raise ValueError(f"not a number: {text!r}")


def tag_value(v):
    return str(v).strip()


C_PARAM = re.compile(r"/\*\*((?:(?!\*/).)*)\*/\s*PARAM_DEFINE_(INT32|FLOAT)\(\s*(\w+)\s*,\s*([^)]*?)\s*\)\s*;", re.S)


def parse_c(text, path):
    out = []
    for m in C_PARAM.finditer(text):
        comment, kind, name, default = m.groups()
        lines = [re.sub(r"^\s*\*\s?", "", ln).strip() for ln in comment.splitlines()]
        lines = [ln for ln in lines if ln is not None]
        short = next((ln for ln in lines if ln and not ln.startswith("@")), "")
        tags = {}
        for ln in lines:
            t = re.match(r"@(\w+)\s*(.*)", ln)
            if t:
                tags.setdefault(t.group(1), t.group(2).strip())
        out.append(entry(name, "INT32" if kind == "INT32" else "FLOAT", number(default), tags, short, path))
    return out


def entry(name, kind, default, tags, short, path):
    lo, hi = tags.get("min", ""), tags.get("max", "")
    if "boolean" in tags:
        lo, hi = "0", "1"
    return {
        "name": name,
        "type": kind,
        "default": default,
        "min": number(lo) if lo != "" else None,
        "max": number(hi) if hi != "" else None,
        "unit": tags.get("unit", ""),
        "description": short.rstrip("."),
        "source": path,
    }


def yaml_param(name, p, group_i, i, path):
    t = p["type"]
    kind = "FLOAT" if t == "float" else "INT32"
    tags = {}
    for k in ("min", "max", "unit"):
        if k in p:
            tags[k] = tag_value(p[k])
    if t == "boolean":
        tags["boolean"] = ""
    if t == "bitmask":
        tags["min"] = "0"
        tags["max"] = str((1 << (max(p["bit"]) + 1)) - 1)
    d = p.get("default", 0)
    if isinstance(d, list):
        d = d[i]
    if isinstance(d, bool):
        d = int(d)
    label = p.get("instance_start_label", p.get("instance_start", 0)) + i
    short = str(p["description"]["short"]).replace("${i}", str(label)).replace("\n", " ")
    return entry(name.replace("${i}", str(group_i)), kind, number(str(d)), tags, short, path)


def parse_yaml(text, path, ethernet):
    cfg = yaml.safe_load(text) or {}
    out = []
    for section in cfg.get("parameters", []) or []:
        for name, plist in (section.get("definitions") or {}).items():
            for p in plist if isinstance(plist, list) else [plist]:
                if p.get("requires_ethernet", False) and not ethernet:
                    continue
                start = p.get("instance_start", 0)
                for i in range(p.get("num_instances", 1)):
                    out.append(yaml_param(name, p, start + i, i, path))
    out.extend(actuator_output(cfg, path))
    return out


def actuator_output(cfg, path):
    """PX4's generated output parameters (Tools/module_config/generate_params.py)."""
    if "actuator_output" not in cfg:
        return []
    out, prefixes = [], []
    module = cfg["module_name"]
    for g in cfg["actuator_output"]["output_groups"]:
        if "generator" in g:
            continue  # timer-generated PWM outputs of real boards
        prefix = g["param_prefix"].replace("${PWM_MAIN_OR_AUX}", "PWM_MAIN")
        label = g["channel_label"]
        if g.get("channel_label_module_name_prefix", True):
            label = f"{module} {label}".replace("${PWM_MAIN_OR_AUX}", "PWM MAIN")
        start = g.get("instance_start", 1)
        n = g["num_channels"]
        prefixes.append(prefix)
        for c in range(start, start + n):
            out.append(entry(f"{prefix}_FUNC{c}", "INT32", 0, {}, f"{label} {c} Output Function", path))
            for key, lab, suffix in (("disarmed", "Disarmed", "DIS"), ("min", "Minimum", "MIN"),
                                     ("max", "Maximum", "MAX"), ("failsafe", "Failsafe", "FAIL")):
                sp = g.get("standard_params", {}).get(key)
                if sp is None:
                    continue
                lo, d = (-1, -1) if key == "failsafe" else (sp["min"], sp["default"])
                out.append(entry(f"{prefix}_{suffix}{c}", "INT32", d,
                                 {"min": str(lo), "max": str(sp["max"])}, f"{label} {c} {lab} Value", path))
    for prefix in dict.fromkeys(prefixes):
        bits = sum(g["num_channels"] for g in cfg["actuator_output"]["output_groups"]
                   if "generator" not in g and g["param_prefix"] == prefix)
        out.append(entry(f"{prefix}_REV", "INT32", 0, {"min": "0", "max": str((1 << bits) - 1)},
                         f"Reverse Output Range for {module}", path))
    return out


def boot_defaults(git_dir, commit):
    """(name, value, script) in the order the SITL boot applies them."""
    applied = []
    values = {}

    def run(path):
        # one [runs, taken] per open `if`: whether the current branch runs, whether one already ran
        stack = []
        for raw in show(git_dir, commit, path).splitlines():
            line = raw.split("#", 1)[0].strip()
            if not line:
                continue
            word = line.split()[0]
            if word in ("if", "elif"):
                cond = re.match(r"(?:if|elif)\s+(!\s+)?param (compare|greater)( -s)? (\w+) (\S+)$", line)
                if cond:
                    neg, op, _, name, v = cond.groups()
                    cur = values.get(name)
                    ok = "$" not in v and cur is not None and (
                        cur == number(v) if op == "compare" else cur > number(v))
                    ok = ok != bool(neg)
                else:
                    # a shell test of the environment: a fresh SITL boot takes the first branch
                    ok = word == "if"
                if word == "if":
                    stack.append([ok, ok])
                else:
                    top = stack[-1]
                    top[0] = ok and not top[1]
                    top[1] = top[1] or ok
                continue
            if word == "else":
                stack[-1][0] = not stack[-1][1]
                continue
            if word == "fi":
                stack.pop()
                continue
            if not all(runs for runs, _ in stack):
                continue
            m = re.match(r"param\s+(set-default|set)(\s+-s)?\s+(\w+)\s+(\S+)", line)
            if m:
                name, v = m.group(3), m.group(4)
                if name in TRANSIENT:
                    continue
                v = SHELL_VALUES.get(name, v)
                if "$" in v:
                    continue
                values[name] = number(v)
                applied.append((name, number(v), path))
                continue
            s = re.match(r"\.\s+(\S+)", line)
            if s and s.group(1) in SOURCED:
                run(SOURCED[s.group(1)])

    def seed(params):
        for p in params:
            values.setdefault(p["name"], p["default"])

    return run, seed, applied


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--git-dir", required=True)
    ap.add_argument("--commit", required=True)
    args = ap.parse_args()
    board = show(args.git_dir, args.commit, "boards/px4/sitl/default.px4board")
    built = board_modules(board)
    ethernet = "CONFIG_BOARD_ETHERNET=y" in board
    dirs = []
    for m in STARTED:
        top = m.split("/")[0]
        if top not in built and m not in built:
            print(f"not built for SITL, skipped: {m}", file=sys.stderr)
            continue
        dirs.append(f"src/modules/{m}/")
    dirs += [f"src/lib/{lib}/" for lib in LIBS]
    files = git(["ls-tree", "-r", "--name-only", args.commit, "src/"], args.git_dir).decode().splitlines()
    params = {}
    for f in sorted(files):
        if not any(f.startswith(d) for d in dirs) or f in SKIP_FILES or "/test" in f:
            continue
        if f.endswith(".c"):
            if "CMSIS" in f:
                continue  # vendored DSP library of gyro_fft: no parameters (and blobs too big for some mirrors)
            text = show(args.git_dir, args.commit, f)
            found = parse_c(text, f) if "PARAM_DEFINE_" in text else []
        elif f.endswith(".yaml"):
            text = show(args.git_dir, args.commit, f)
            if not re.search(r"^(parameters|actuator_output):", text, re.M):
                continue
            found = parse_yaml(text, f, ethernet)
        else:
            continue
        for p in found:
            if p["name"] in params and params[p["name"]]["source"] != f:
                print(f"{p['name']} declared twice: {params[p['name']]['source']} and {f}", file=sys.stderr)
            params.setdefault(p["name"], p)
    run, seed, applied = boot_defaults(args.git_dir, args.commit)
    seed(params.values())
    for s in SCRIPTS:
        run(s)
    for name, v, script in applied:
        if name not in params:
            print(f"startup script sets {name} (not in the selection): {script}", file=sys.stderr)
            continue
        p = params[name]
        p["default"] = int(v) if p["type"] == "INT32" else float(v)
        p["boot_source"] = script
    print(f"# PX4 SITL multicopter (gz_x500) boot parameters, PX4-Autopilot commit {args.commit}")
    print("# generated by tools/px4_params.py; columns: name type default min max unit description source")
    for name in sorted(params):
        p = params[name]
        src = p["source"] + (f" (default: {p['boot_source']})" if "boot_source" in p else "")
        cols = [name, p["type"], fmt(p["default"], p["type"]), fmt(p["min"], p["type"]), fmt(p["max"], p["type"]),
                p["unit"], p["description"].replace("\t", " "), src]
        print("\t".join(cols))
    print(f"{len(params)} parameters", file=sys.stderr)


def fmt(v, kind):
    if v is None:
        return ""
    if kind == "INT32":
        return str(int(v))
    return repr(float(v))


if __name__ == "__main__":
    main()
