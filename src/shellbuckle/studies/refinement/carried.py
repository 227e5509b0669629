"""States carried from each coarse mesh to the finest mesh of the study and relaxed there
(:func:`carry`), kept in ``carried.json`` and read into the table's runs
(:func:`with_carried`)."""

from __future__ import annotations

import contextlib
import logging
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ...util import interrupt_of
from .runs import CARRY_AT, carried_columns, collect, step_near
from .table import GROUP

if TYPE_CHECKING:  # pandas is imported where a table is made: not to build the command line
    import pandas as pd

log = logging.getLogger(__name__)

CARRIED_JSON, CARRIED_LOCK = "carried.json", ".carried.lock"
CARRIED_VERSION = 1
#: The run ids an entry keeps of its source and target runs (entries written before they
#: were kept have none, and are taken as carried between the runs now in their folders).
IDS = ("source_id", "target_id")


def run_identity(path) -> str | None:
    """The run id of the run folder ``path`` (``run.json``), None where it cannot be read: a
    run made again in the same folder has another."""
    import json

    from ...store.names import RUN_JSON

    try:
        run_id = json.loads((Path(path) / RUN_JSON).read_text(encoding="utf-8")).get("run_id")
    except (OSError, UnicodeDecodeError, ValueError, AttributeError):
        return None
    return run_id if isinstance(run_id, str) else None


def _ids(source, target) -> dict:
    return {"source_id": run_identity(source), "target_id": run_identity(target)}


def _same_runs(entry: dict, ids: dict) -> bool:
    """Whether ``entry`` was carried between the runs whose ids are ``ids`` (:data:`IDS`);
    an entry without ids is taken as such."""
    return all(entry.get(f) is None or entry.get(f) == ids.get(f) for f in IDS)


def _name(path, out) -> str:
    """How a run is named in :data:`CARRIED_JSON`: its folder relative to the study folder
    ``out`` when it lies in it, else its absolute path."""
    path, out = Path(path).resolve(), Path(out).resolve()
    return str(path.relative_to(out)) if path.is_relative_to(out) else str(path)


def _carry_key(source: str, step: int, target: str, at: float) -> str:
    return f"{source} {step} -> {target} at {at:g}"


def read_carried(out, *, strict: bool = False) -> dict:
    """The carried states kept in the study folder ``out`` (:data:`CARRIED_JSON`): ``{key:
    entry}``, empty if there are none. A file that cannot be read, or of another version, is
    a ``RuntimeError`` naming it with ``strict`` (:func:`carry` does not write over it), else
    a warning and no entries (the report goes on without them)."""
    import json

    path = Path(out) / CARRIED_JSON
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(data, dict) or not isinstance(data.get("carried"), dict):
            raise ValueError("not a record of carried states")
        if data.get("version") != CARRIED_VERSION:
            raise ValueError(f"version {data.get('version')!r}, this version reads "
                             f"{CARRIED_VERSION}")
        for key, entry in data["carried"].items():
            problem = _entry_problem(entry)
            if problem is not None:
                raise ValueError(f"entry {key!r}: {problem}")
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        why = f"{path}: {exc}"
        if strict:
            raise RuntimeError(f"{why}; move it away to carry the states again") from None
        log.warning("%s: the carried states are left out of the report", why)
        return {}
    return dict(data["carried"])


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _entry_problem(entry) -> str | None:
    """What is wrong with an entry of :data:`CARRIED_JSON` (None: nothing): it names its runs,
    step and volume fraction, and holds ``failed`` or the numbers the report reads."""
    if not isinstance(entry, dict):
        return "not a record"
    for field, ok in (("source", str), ("target", str), ("step", int)):
        if not isinstance(entry.get(field), ok) or isinstance(entry.get(field), bool):
            return f"no {field}"
    if not _is_number(entry.get("at")):
        return "no at"
    if any(entry.get(f) is not None and not isinstance(entry[f], str) for f in IDS):
        return "a run id that is no text"
    if "failed" in entry:
        return None
    if not isinstance(entry.get("certified"), bool) or not _is_number(entry.get("own_W")):
        return "no certified or own_W"
    if entry["certified"] and not (_is_number(entry.get("W")) and (
            entry.get("relative") is None or _is_number(entry.get("relative")))):
        return "certified without W or relative"
    return None


def _keep(out, key: str, entry: dict) -> dict:
    """Add ``entry`` under ``key`` to :data:`CARRIED_JSON` in ``out``, merged with what the
    file holds now (under its lock, so that two processes carrying states into one study
    lose none of each other's; a failure does not replace a state carried meanwhile); returns
    every kept entry."""
    import json

    from ...store.atomic import atomic_write_bytes, locked_update
    from ...util import json_safe

    Path(out).mkdir(parents=True, exist_ok=True)
    with locked_update(Path(out), CARRIED_JSON, CARRIED_LOCK):
        carried = read_carried(out, strict=True)
        if _done(carried, key, entry) and "failed" in entry:
            return carried  # another process carried it meanwhile: its result stays
        carried[key] = entry
        text = json.dumps(json_safe({"version": CARRIED_VERSION, "carried": carried}),
                          indent=1)
        atomic_write_bytes(Path(out) / CARRIED_JSON, (text + "\n").encode())
    return carried


def _done(carried: dict, key: str, ids: dict) -> bool:
    """Whether ``carried`` holds the state ``key`` carried (kept, not as failed, and between
    the runs of ``ids``: a run made again since is carried again)."""
    return key in carried and "failed" not in carried[key] and _same_runs(carried[key], ids)


def _finest_runs(runs: pd.DataFrame, vertices: int | None = None) -> dict:
    """Per group and seed, the path of the run on the group's finest mesh (over all seeds;
    a seed without a finished run there has none); with ``vertices``, only of groups whose
    finest mesh has that many vertices (a study whose finest mesh has no run yet has
    none)."""
    finest = {}
    for key, group in runs.groupby(GROUP, sort=True):
        if vertices is not None and group["n_vertices"].max() != vertices:
            continue
        top = group[group["n_vertices"] == group["n_vertices"].max()]
        for seed, rows in top.groupby("seed"):
            if len(rows) == 1:
                finest[(*key, seed)] = str(rows["path"].iloc[0])
    return finest


def carry_pairs(runs: pd.DataFrame, at: float = CARRY_AT, *,
                finest_vertices: int | None = None) -> list[tuple]:
    """The (source folder, step, finest folder) of :func:`carry`: per group and seed, each
    coarser mesh's run, its stored step nearest dV/V = ``at`` (within half a step: a run that
    ended before has none), and the run of the same seed on the group's finest mesh, which
    holds a step at that step's dV/V (pairs without one are left out); with
    ``finest_vertices``, only to a finest mesh of that many vertices."""
    from ...store.run import RunStore
    from ..transfer import own_step

    pairs = []
    finest = _finest_runs(runs, finest_vertices)
    for _, row in runs.iterrows():
        target = finest.get((*(row[c] for c in GROUP), row["seed"]))
        if target is None or str(row["path"]) == target:
            continue
        table = RunStore.open(row["path"]).table()
        k = step_near(table, at)
        if k is None or k == 0:  # the reference sphere is not carried
            continue
        dv = float(table.loc[table["step"] == k, "dV_over_V"].iloc[0])
        if own_step(target, dv) is not None:
            pairs.append((str(row["path"]), k, target))
    return pairs


def _carried_entry(source: str, k: int, target: str, threads: int | None) -> dict:
    """What :data:`CARRIED_JSON` keeps of one carried state (without its names): the
    comparison's numbers, or ``failed`` with the reason where the relaxation failed (an
    interrupt is raised, not kept)."""
    from ..transfer import compare

    log.info("carrying step %d of %s to %s", k, source, target)
    try:
        c = compare(source, k, target, threads=threads)
    except Exception as exc:  # a failed relaxation is kept as such, the others go on
        if interrupt_of(exc) is not None:
            raise
        return {"failed": f"{type(exc).__name__}: {exc}", "certified": False}
    return {"dV_over_V": c.dV_over_V, "shape": c.carried.shape, "W": c.carried.W,
            "E_over_kappa": c.carried.E_over_kappa, "source_W": c.source.W,
            "own_shape": c.own.shape, "own_W": c.own.W, "own_E_over_kappa": c.own.E_over_kappa,
            "relative": c.relative, "certified": c.certified}


def _carried_in_processes(pairs, threads, workers):
    """``(pair, entry)`` of :func:`_carried_entry` for each pair as a worker process ends it
    (``min(workers, len(pairs))`` fresh processes, each PARDISO on ``threads`` and BLAS on
    one, which ignore SIGINT: an interrupt reaches this process, which stops them, as it does
    whenever the caller stops iterating); RuntimeError where a worker dies (killed, out of
    memory) before its states are done. What the workers log reaches this process's handlers
    (the command line's format and level)."""
    import multiprocessing
    import queue

    context = multiprocessing.get_context("spawn")
    tasks, results = context.Queue(), context.Queue()
    n = min(workers, len(pairs))
    for i, pair in enumerate(pairs):
        tasks.put((i, (*pair, threads)))
    for _ in range(n):
        tasks.put(None)  # one end mark per worker
    level = logging.getLogger("shellbuckle").getEffectiveLevel()
    processes = [context.Process(target=_carry_worker,
                                 args=(tasks, results, level, os.getpid()), daemon=True)
                 for _ in range(n)]
    for process in processes:
        process.start()
    try:
        for _ in pairs:
            while True:
                try:
                    item = results.get(timeout=1.0)
                except queue.Empty:
                    dead = [p.exitcode for p in processes if p.exitcode not in (None, 0)]
                    if not dead and all(p.exitcode is not None for p in processes):
                        dead = [0]  # every worker ended, a state is missing all the same
                    if dead:
                        raise RuntimeError(
                            f"a process carrying states to the finest mesh died (exit code "
                            f"{dead[0]}: killed, or out of memory?); the states carried so far "
                            "are kept: run again, with fewer workers") from None
                    continue
                if not isinstance(item, logging.LogRecord):
                    break
                logger = logging.getLogger(item.name)  # a worker's message, as if logged here
                if logger.isEnabledFor(item.levelno):
                    logger.handle(item)
            i, entry = item
            yield pairs[i], entry
    finally:
        for process in processes:
            if process.is_alive():
                process.terminate()
        for process in processes:
            process.join()
        tasks.cancel_join_thread()  # states not started are dropped, not waited for at exit


def _carry_worker(tasks, results, level: int, parent: int) -> None:
    """A worker process of :func:`_carried_in_processes`: carries the states it is given until
    the end mark; shellbuckle's log records at ``level`` or above go to ``results`` (the
    calling process handles them). It ends within a second of its parent (the process
    ``parent``), however that ends (a SIGKILL leaves no one to stop it)."""
    import logging.handlers
    import signal
    import threading

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles it and stops the workers
    threading.Thread(target=_end_with, args=(parent,), daemon=True).start()
    logger = logging.getLogger("shellbuckle")
    logger.setLevel(level)
    logger.addHandler(logging.handlers.QueueHandler(results))
    logger.propagate = False
    while (task := tasks.get()) is not None:
        i, args = task
        results.put((i, _carried_entry(*args)))


def _end_with(parent: int) -> None:
    """End this process as soon as the process ``parent`` is no longer its parent."""
    import time

    while os.getppid() == parent:
        time.sleep(1.0)
    os._exit(1)


def carry(out, paths=None, *, at: float = CARRY_AT, threads: int | None = 1,
          workers: int | None = 1, progress: bool = False,
          finest_vertices: int | None = None) -> dict:
    """Carry, per group and seed, each coarser mesh's step nearest dV/V = ``at`` to the finest
    mesh (:func:`carry_pairs`, :func:`shellbuckle.studies.transfer.compare`) and keep what it
    gives in ``out``/:data:`CARRIED_JSON`, each pair written as soon as it is done (a pair
    already kept is not computed again): the carried state's class and W on the finest mesh,
    its energy and that of the finest mesh's own step, their relative difference, whether it
    relaxed to a certified minimum; a relaxation that fails (it left the physical domain) is
    kept as ``failed`` with its reason, reported as no value, and tried again by the next
    call. ``paths``: the runs (default every run of the sweep folder ``out``); ``workers``:
    processes relaxing pairs at once (each on ``threads``; the same numbers as one at a time,
    this process writing the file); ``finest_vertices``: carry only to a finest mesh of that
    many vertices (a study's finest mesh, before its runs there exist). Returns every kept
    entry."""
    carried = read_carried(out, strict=True)
    paths = [out] if paths is None else list(paths)
    if not paths:
        return carried
    pairs = [p for p in carry_pairs(collect(paths, ()), at, finest_vertices=finest_vertices)
             if not _done(carried, _carry_key(_name(p[0], out), p[1], _name(p[2], out), at),
                          _ids(p[0], p[2]))]
    bar = None
    if progress and pairs:
        from tqdm import tqdm

        bar = tqdm(total=len(pairs), desc="carrying to the finest mesh", unit="state")
    done = (_carried_in_processes(pairs, threads, workers) if (workers or 1) > 1
            and len(pairs) > 1 else ((p, _carried_entry(*p, threads)) for p in pairs))
    try:
        with contextlib.closing(done):  # the workers stop with this loop, however it ends
            for (source, k, target), entry in done:
                names = {"source": _name(source, out), "step": k,
                         "target": _name(target, out), "at": at} | _ids(source, target)
                key = _carry_key(names["source"], k, names["target"], at)
                if "failed" in entry:
                    log.warning("carrying %s failed: %s", key, entry["failed"])
                carried = _keep(out, key, names | entry)
                if bar is not None:
                    bar.update()
    finally:
        if bar is not None:
            bar.close()
    return carried


def with_carried(runs: pd.DataFrame, carried: dict, out, at: float = CARRY_AT) -> pd.DataFrame:
    """``runs`` with the columns of :func:`carried_columns` from the entries of ``carried``
    (:func:`read_carried` of the study folder ``out``) carried at ``at`` from a run of
    ``runs`` to the run of its seed on its group's finest mesh: a coarse run, the W of its
    state carried there and the relative energy in percent (no value where the carried
    state is no certified minimum); the finest run, its own W and 0. An entry carried
    between runs made again since (other run ids) is left out, with a warning. Without such
    entries, ``runs`` unchanged."""
    if not carried or runs.empty:
        return runs
    w_col, e_col = carried_columns(at)
    row_of = {_name(p, out): i for i, p in enumerate(runs["path"])}
    id_of = {_name(p, out): run_identity(p) for p in runs["path"]}
    finest = {_name(p, out) for p in _finest_runs(runs).values()}
    W, dE = np.full(len(runs), np.nan), np.full(len(runs), np.nan)
    for entry in carried.values():
        source, target = entry.get("source"), entry.get("target")
        if (entry.get("at") != at or "failed" in entry or target not in finest
                or source not in row_of or source == target):
            continue
        if not _same_runs(entry, {"source_id": id_of[source], "target_id": id_of[target]}):
            log.warning("the state of %s step %s carried to %s was carried from runs made "
                        "again since: left out of the report (carry it again)", source,
                        entry.get("step"), target)
            continue
        i, j = row_of[source], row_of[target]
        if entry.get("certified"):
            relative = entry.get("relative")
            W[i] = entry["W"]
            dE[i] = math.nan if relative is None else 100.0 * float(relative)
        W[j], dE[j] = entry["own_W"], 0.0
    if np.isnan(W).all():
        return runs
    runs = runs.copy()
    runs[w_col], runs[e_col] = W, dE
    return runs
