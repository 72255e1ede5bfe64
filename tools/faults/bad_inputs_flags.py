"""Generated cases of the fault-injection harness (``tools/faults/bad_inputs.py``): each bad value of
each flag of each command.

Two kinds of refusal are stated. A value that is no number of the flag's type ("abc", "1.5" for an
integer, an empty value, a choice that is not offered) is argparse's usage error: status 2, its last
line ``platebench CMD: error: argument FLAG: ...``. A value of the right type out of the allowed range
(NaN, infinity, zero, a negative count, a size beyond the limit) is PlateBench's own refusal: status 2
and one line ``platebench: error: ...`` that names the flag (or the configuration key it sets).
Every case also states that its output folder does not appear.
"""
from __future__ import annotations

from tools.faults.bad_inputs import Case, register_cases

OUT = "o_flag"
SIZE = ("--width", "160", "--height", "120", "--spp", "1")


def _names(flag: str, stem: str = "") -> tuple:
    """The words that name ``flag`` in a refusal: the flag, its dotted key's spelling, a stem."""
    bare = flag.lstrip("-")
    return tuple(x for x in (flag, bare, bare.replace("-", "_"), stem) if x)


# command -> (its arguments before the flag, the flags given to it always)
SAMPLE_COMMANDS = {
    "render": ["render"],
    "sense": ["sense"],
    "calibrate": ["calibrate"],
}
# flag -> (type, values PlateBench refuses, stem of its configuration key)
SAMPLE_FLAGS = {
    "--bend-deg": (float, ("nan", "inf", "-inf", "-1", "351", "1e-12"), "bend"),
    "--bend-axis-deg": (float, ("nan", "inf", "-inf"), "axis"),
    "--distance-m": (float, ("nan", "inf", "-inf", "0", "-0.4"), "distance"),
    "--width": (int, ("0", "-1", "10", "99999999999"), "width"),
    "--height": (int, ("0", "-1", "99999999999"), "height"),
    "--spp": (int, ("0", "-1", "99999999999"), "spp"),
    "--seed": (int, ("-1", "99999999999"), "seed"),
    "--realism-seed": (int, ("-1", "99999999999"), "realism"),
    "--grid": (str, ("abc", "4x4", "0x0@40", "4x4@0"), "grid"),
}
NOT_OF_TYPE = {float: ("abc", ""), int: ("abc", "1.5", "")}
CHOICES = {"--bend-direction": "sideways", "--camera": "pinhole9", "--realism": "perfect"}


def _sample_flag_cases() -> list[Case]:
    c = []
    for cmd, head in SAMPLE_COMMANDS.items():
        for flag, (kind, values, stem) in SAMPLE_FLAGS.items():
            i = SIZE.index(flag) if flag in SIZE else None  # the tiny size's own flag: its value left out
            rest = list(SIZE) if i is None else list(SIZE[:i] + SIZE[i + 2:])
            for v in values:
                c.append(Case(f"flag: {cmd} {flag} {v}", [*head, "--out", f"{{W}}/{OUT}", *rest, f"{flag}={v}"],
                              (_names(flag, stem),), watch=(OUT,), family="flag-range", timeout_s=60))
            for v in NOT_OF_TYPE.get(kind, ()):
                c.append(Case(f"flag: {cmd} {flag} {v or 'empty'}", [*head, "--out", f"{{W}}/{OUT}", *rest,
                                                                     f"{flag}={v}"],
                              (flag,), watch=(OUT,), usage=True, family="flag-type", timeout_s=60))
        for flag, v in CHOICES.items():
            c.append(Case(f"flag: {cmd} {flag} {v}", [*head, "--out", f"{{W}}/{OUT}", *SIZE, flag, v], (flag,),
                          watch=(OUT,), usage=True, family="flag-type", timeout_s=60))
        c.append(Case(f"flag: {cmd} --config missing", [*head, "--out", f"{{W}}/{OUT}", "--config",
                                                        "{W}/none.toml"], ("none.toml",), watch=(OUT,),
                      family="flag-range", timeout_s=60))
    return c


# (name, argv before the bad flag, flag, values refused (range), values not of its type)
OTHER_FLAGS = (
    ("reconstruct", ["reconstruct", "{W}/good"], "--grid-mm", ("nan", "inf", "0", "-1"), ("abc",)),
    ("compare", ["compare", "{W}/good", "--methods", "sgbm"], "--spp", ("0", "-1", "99999999999"), ("abc",)),
    ("compare", ["compare", "{W}/good", "--methods", "sgbm"], "--min-depth-mm", ("nan", "-inf", "-1"), ("abc",)),
    ("compare", ["compare", "{W}/good", "--methods", "sgbm"], "--max-depth-mm", ("nan", "inf", "0"), ("abc",)),
    ("compare", ["compare", "{W}/good", "--methods", "sgbm"], "--method-time-limit-s", ("nan", "0", "-1"),
     ("abc",)),
    ("evaluate", ["evaluate", "{W}/good", "{W}/good_recon"], "--outlier-mm", ("nan", "-1", "0"), ("abc",)),
    ("evaluate", ["evaluate", "{W}/good", "{W}/good_recon"], "--radius-mm", ("nan", "-1", "0"), ("abc",)),
    ("export", ["export", "{W}/ds", "--format", "middlebury"], "--shift", ("-1", "100000", "nan"), ()),
    ("sweep", ["sweep", "{W}/ds.toml", "--no-progress"], "--workers", ("-1", "100000"), ("abc", "1.5")),
    ("sweep", ["sweep", "{W}/ds.toml", "--no-progress", "--scheduler", "tcp://127.0.0.1:{PORT}"],
     "--connect-timeout-s", ("nan", "-1", "0"), ("abc",)),
    ("sweep", ["sweep", "{W}/ds.toml", "--no-progress"], "--worker-timeout-s", ("nan", "-1"), ("abc",)),
    ("sweep", ["sweep", "{W}/ds.toml", "--no-progress"], "--method-time-limit-s", ("nan", "-1"), ("abc",)),
    ("sense", ["sense", *SIZE], "--max-cures", ("-1",), ("abc",)),
    ("sense", ["sense", *SIZE], "--workspace-mm", ("nan", "-1", "0"), ("abc",)),
    ("sense", ["sense", *SIZE], "--verify-grid", ("abc", "0x0@40"), ()),
    ("study false-boundary", ["study", "false-boundary"], "--bend", ("a:b", "0:10:0", "nan"), ()),
    ("study false-boundary", ["study", "false-boundary"], "--limit", ("-1",), ("abc",)),
    ("study false-boundary", ["study", "false-boundary"], "--width", ("0", "10", "99999999"), ("abc",)),
    ("study false-boundary", ["study", "false-boundary"], "--spp", ("0", "-1"), ("abc",)),
    ("study false-boundary", ["study", "false-boundary"], "--workers", ("-1",), ("abc",)),
    ("study false-boundary", ["study", "false-boundary"], "--aspect", ("0", "nan", "-1"), ()),
    ("study false-boundary", ["study", "false-boundary"], "--axes", ("nan", "a"), ()),
    ("study false-boundary", ["study", "false-boundary"], "--families", ("nosuchfamily",), ()),
    ("study false-boundary", ["study", "false-boundary"], "--realism-scale", ("nosuch=1", "noise=nan"), ()),
    ("study accuracy", ["study", "accuracy"], "--draws", ("0", "-1", "1000000000"), ("abc",)),
    ("study accuracy", ["study", "accuracy"], "--spp", ("0",), ("abc",)),
    ("study accuracy", ["study", "accuracy"], "--seed", ("-1",), ("abc",)),
    ("study accuracy", ["study", "accuracy"], "--targets", ("nosuch",), ()),
    ("study cut-squares", ["study", "cut-squares"], "--bend", ("nan", "a:b"), ()),
    ("study cut-squares", ["study", "cut-squares"], "--axes", ("nan",), ()),
    ("study cut-squares", ["study", "cut-squares"], "--distances", ("0", "-1", "nan"), ()),
    ("study cut-squares", ["study", "cut-squares"], "--spp", ("0",), ("abc",)),
    ("calibrate", ["calibrate", *SIZE], "--target-z-mm", ("nan", "-1"), ("abc",)),
    ("perf", ["perf", "render"], "--repeat", ("0", "-1"), ("abc",)),
)
# (name, argv, what the one line must name): values of no flag in particular
OTHER_REFUSALS = (
    ("compare --methods empty", ["compare", "{W}/good", "--methods", "", "--out", "{W}/o_flag"], ("--methods",)),
    ("compare --methods nosuch", ["compare", "{W}/good", "--methods", "nosuch", "--out", "{W}/o_flag"],
     ("nosuch",)),
    ("compare --min-depth-mm above --max-depth-mm", ["compare", "{W}/good", "--methods", "sgbm", "--min-depth-mm",
                                                     "500", "--max-depth-mm", "100", "--out", "{W}/o_flag"],
     (("--min-depth-mm", "--max-depth-mm", "depth range"), "500")),
    ("sweep --methods nosuch", ["sweep", "{W}/ds.toml", "--methods", "nosuch", "--out", "{W}/o_flag"], ("nosuch",)),
    ("sweep --example nosuch", ["sweep", "--example", "nosuch", "--out", "{W}/o_flag"], ("nosuch",)),
    ("sweep without --out", ["sweep", "{W}/ds.toml"], ("--out",)),
    ("perf nosuch target", ["perf", "nosuch"], ("nosuch",)),
    ("perf --save not .npz", ["perf", "variants", "--save", "{W}/o_flag.txt"], (".npz",)),
    ("benchmark build nosuch split", ["benchmark", "build", "nosuch", "--out", "{W}/o_flag"], ("nosuch",)),
    ("benchmark verify a missing folder", ["benchmark", "verify", "{W}/nothing"], ("nothing",)),
    ("report a missing folder", ["report", "{W}/nothing", "--out", "{W}/o_flag"], ("nothing",)),
    ("report a file", ["report", "{W}/ds.toml", "--out", "{W}/o_flag"], ("ds.toml",)),
    ("evaluate a missing reconstruction", ["evaluate", "{W}/good", "{W}/nothing"], ("nothing",)),
    ("evaluate no reconstruction given", ["evaluate", "{W}/good"], (("RECON_DIR", "--disparity", "--points"),)),
    ("reconstruct --calibration missing", ["reconstruct", "{W}/good", "--out", "{W}/o_flag", "--calibration",
                                           "{W}/none.json"], ("none.json",)),
)

USAGE_REFUSALS = {"compare --methods empty"}  # refused by the flag's argparse type: a usage error


def _other_flag_cases() -> list[Case]:
    c = []
    for name, head, flag, values, untyped in OTHER_FLAGS:
        out = [] if name.startswith("perf") else ["--out", f"{{W}}/{OUT}"]
        for v in values:
            c.append(Case(f"flag: {name} {flag} {v}", [*head, *out, f"{flag}={v}"], (_names(flag),), watch=(OUT,),
                          family="flag-range", timeout_s=60))
        for v in untyped:
            c.append(Case(f"flag: {name} {flag} {v}", [*head, *out, f"{flag}={v}"], (flag,), watch=(OUT,),
                          usage=True, family="flag-type", timeout_s=60))
    for name, argv, expect in OTHER_REFUSALS:
        usage = name in USAGE_REFUSALS
        c.append(Case(f"flag: {name}", argv, expect, watch=(OUT,), family="flag-type" if usage else "flag-range",
                      timeout_s=60, usage=usage))
    c.append(Case("flag: export a sample, not a dataset (exported as one)", ["export", "{W}/good", "--format",
                                                                             "kitti", "--out", "{W}/o_flag"], (),
                  expect_rc=0, family="flag-range", timeout_s=60,
                  check=lambda w, rc, out, err: None if (w / OUT).is_dir() else "nothing was exported"))
    return c


@register_cases
def flag_cases() -> list[Case]:
    """Each bad value of each flag of each command (module doc)."""
    return _sample_flag_cases() + _other_flag_cases()
