"""Bad input is refused before any work (docs/errors.md): exit code 2 and one line on stderr
that names the option and the value as typed; no file or folder is made."""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys

import meshio
import pytest

from shellbuckle.cli import build_parser, main
from shellbuckle.commands._checks import (MAX_VERTICES, MIN_VERTICES, degree_resolved,
                                          gamma_resolved, mean_edge, vertices_needed)
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.run import deflate


@pytest.fixture(scope="module")
def places(tmp_path_factory):
    """A one-step run on 42 vertices, an empty folder, a file, a read-only folder."""
    root = tmp_path_factory.mktemp("places")
    run = deflate(icosphere(2), ShellParameters.from_gamma(271.0), dv=0.05, until=0.05,
                  seed=1, out=root / "run")
    (root / "empty").mkdir()
    (root / "afile.txt").write_text("not a mesh\n")
    (root / "full").mkdir()
    (root / "full" / "notes.txt").write_text("x\n")
    (root / "ro").mkdir()
    os.chmod(root / "ro", 0o555)
    (root / "blank.vtk").write_bytes(b"")
    (root / "steps_link").symlink_to(run.path / "steps", target_is_directory=True)
    (root / "loop").symlink_to(root / "loop")  # a loop of symbolic links
    (root / "bad.vtu").write_text("garbage\n")
    unit = icosphere(3)  # radius 1: not a 20 nm shell
    meshio.write_points_cells(str(root / "unit.vtk"), unit.X, [("triangle", unit.faces)])
    yield {"run": str(run.path), "empty": str(root / "empty"), "file": str(root / "afile.txt"),
           "full": str(root / "full"), "ro": str(root / "ro"), "root": root,
           "blankvtk": str(root / "blank.vtk"), "badvtu": str(root / "bad.vtu"),
           "link": str(root / "steps_link"), "loop": str(root / "loop"),
           "unitvtk": str(root / "unit.vtk")}
    os.chmod(root / "ro", 0o755)


# (argv, option, value as typed); {run} {empty} {file} {full} {ro} {tmp} are filled in.
NUMBERS = [
    ("--gamma", "0"), ("--gamma", "-1e3"), ("--gamma", "1e300"), ("--gamma", "abc"),
    ("--gamma", "nan"), ("--gamma", "inf"), ("--gamma", "-inf"), ("--gamma", "0.5"),
    ("--gamma", "1e12"), ("--nu", "0.5"), ("--nu", "-1"), ("--nu", "1.5"), ("--nu", "x"),
    ("--nu", "nan"),
]
CASES = [
    *[(["theory", flag, value], flag, value) for flag, value in NUMBERS],
    *[(["deflate", flag, value, "--out", "{tmp}/r"], flag, value) for flag, value in NUMBERS],
    (["deflate", "--gamma=-1e300", "--out", "{tmp}/r"], "--gamma", "-1e300"),
    (["deflate", "--dv", "1e-5", "--until", "2e-5", "--out", "{tmp}/r"], "--dv", "1e-5"),
    (["deflate", "--mesh", "{blankvtk}", "--out", "{tmp}/r"], "--mesh", "blank.vtk"),
    # a path shorter than its step; --then-out checked before the path in gamma runs
    (["continue", "{run}", "--until", "0.06", "--out", "{tmp}/r"], "--until", "0.06"),
    (["continue", "{run}", "--until", "0.2", "--out", "{run}"], "--out", "run"),
    (["export", "{run}", "--step", "-1", "--format", "vtk", "--out", "{loop}/x.vtk"], "--out",
     "loop/x.vtk"),
    (["continue", "{run}", "--gamma", "300", "--increments", "1", "--then-deflate-to", "0.1",
      "--then-out", "", "--out", "{tmp}/r"], "--then-out", "''"),
    (["deflate", "--icosphere", "3", "--out", ""], "--out", "''"),
    (["export", "{run}", "--step", "-1", "--format", "vtk", "--out", " "], "--out", "' '"),
    (["continue", "{run}", "--gamma", "300", "--increments", "1", "--then-deflate-to", "0.06",
      "--out", "{tmp}/r"], "--then-deflate-to", "0.06"),
    (["continue", "{run}", "--gamma", "300", "--increments", "1", "--then-deflate-to", "0.1",
      "--then-out", "{run}", "--out", "{tmp}/r"], "--then-out", "run"),
    (["continue", "{run}", "--gamma", "300", "--increments", "1", "--then-deflate-to", "0.1",
      "--then-out", "{tmp}/r", "--out", "{tmp}/r"], "--then-out", "/r"),
    (["deflate", "--mesh", "{badvtu}", "--out", "{tmp}/r"], "--mesh", "bad.vtu"),
    (["deflate", "--schedule", "0.02,0.04", "--dv", "0.01", "--out", "{tmp}/r"], "--dv",
     "0.01"),
    (["continue", "{run}", "--schedule", "0.06", "--until", "0.9", "--out", "{tmp}/c"],
     "--until", "0.9"),
    (["deflate", "--pressures", "1,2", "--until", "0.5", "--out", "{tmp}/r"], "--until", "0.5"),
    (["deflate", "--mesh", "{unitvtk}", "--E", "1e8", "--sigma", "0.5", "--d", "2e-9", "--R",
      "2e-8", "--out", "{tmp}/r"], "--mesh", "unit.vtk"),
    (["classify", "{blankvtk}"], "blank.vtk", "cannot be read as .vtk"),
    (["continue", "{run}", "--dv", "-1e-6", "--until", "0.04", "--out", "{tmp}/r"], "--dv",
     "-1e-6"),
    (["deflate", "--gamma", "1e9", "--vertices", "200", "--out", "{tmp}/r"], "--gamma", "1e9"),
    (["deflate", "--gamma", "2e7", "--out", "{tmp}/r"], "--gamma", "2e7"),
    (["deflate", "--gamma", "20000", "--energy-convention", "paper", "--vertices", "300",
      "--out", "{tmp}/r"], "--gamma", "20000"),
    (["deflate", "--gamma", "5e4", "--icosphere", "5", "--out", "{tmp}/r"], "--gamma", "5e4"),
    (["deflate", "--vertices", "10000000000", "--out", "{tmp}/r"], "--vertices", "10000000000"),
    (["deflate", "--vertices", "2", "--out", "{tmp}/r"], "--vertices", "2"),
    (["deflate", "--vertices", "19", "--out", "{tmp}/r"], "--vertices", "19"),
    (["deflate", "--vertices", "1000001", "--out", "{tmp}/r"], "--vertices", "1000001"),
    (["deflate", "--vertices", "3.5", "--out", "{tmp}/r"], "--vertices", "3.5"),
    (["deflate", "--vertices", "-5", "--out", "{tmp}/r"], "--vertices", "-5"),
    (["deflate", "--vertices", "100", "--out", "{tmp}/r"], "--vertices", "100"),
    (["deflate", "--icosphere", "100000", "--out", "{tmp}/r"], "--icosphere", "100000"),
    (["deflate", "--icosphere", "1", "--out", "{tmp}/r"], "--icosphere", "1"),
    (["deflate", "--icosphere", "0", "--out", "{tmp}/r"], "--icosphere", "0"),
    (["deflate", "--icosphere", "two", "--out", "{tmp}/r"], "--icosphere", "two"),
    (["deflate", "--pressures", "1e4", "--vertices", "200", "--out", "{tmp}/r"],
     "--pressures", "1e4"),
    (["deflate", "--pressures=-1e300", "--out", "{tmp}/r"], "--pressures", "-1e300"),
    (["deflate", "--pressures", "1,2,1e5", "--out", "{tmp}/r"], "--pressures", "1e5"),
    (["deflate", "--pressures", "-2e4", "--out", "{tmp}/r"], "--pressures", "-2e4"),
    (["deflate", "--pressures", "1,abc", "--out", "{tmp}/r"], "--pressures", "abc"),
    (["deflate", "--pressures", "nan", "--out", "{tmp}/r"], "--pressures", "nan"),
    (["deflate", "--schedule", "garbage", "--out", "{tmp}/r"], "--schedule", "garbage"),
    (["deflate", "--schedule", "0.1,0.2,1.5", "--out", "{tmp}/r"], "--schedule", "1.5"),
    (["deflate", "--schedule", "0.1,inf", "--out", "{tmp}/r"], "--schedule", "inf"),
    (["deflate", "--schedule", "-1.5", "--out", "{tmp}/r"], "--schedule", "-1.5"),
    (["deflate", "--until", "1.5", "--out", "{tmp}/r"], "--until", "1.5"),
    (["deflate", "--until", "0.99", "--out", "{tmp}/r"], "--until", "0.99"),
    (["deflate", "--until", "nan", "--out", "{tmp}/r"], "--until", "nan"),
    (["deflate", "--until", "0.001", "--out", "{tmp}/r"], "--until", "0.001"),
    (["deflate", "--dv", "nan", "--out", "{tmp}/r"], "--dv", "nan"),
    (["deflate", "--dv", "0", "--out", "{tmp}/r"], "--dv", "0"),
    (["deflate", "--dv", "0.6", "--out", "{tmp}/r"], "--dv", "0.6"),
    (["deflate", "--dv", "-0.01", "--out", "{tmp}/r"], "--dv", "-0.01"),
    (["deflate", "--dv", "1e-7", "--out", "{tmp}/r"], "--dv", "1e-7"),
    (["deflate", "--dv", "1e-300", "--out", "{tmp}/r"], "--dv", "1e-300"),
    (["deflate", "--seed", "-1", "--out", "{tmp}/r"], "--seed", "-1"),
    (["deflate", "--seed", "1.5", "--out", "{tmp}/r"], "--seed", "1.5"),
    (["deflate", "--seed", "99999999999", "--out", "{tmp}/r"], "--seed", "99999999999"),
    (["deflate", "--temperature", "2", "--out", "{tmp}/r"], "--temperature", "2"),
    (["deflate", "--temperature", "-0.1", "--out", "{tmp}/r"], "--temperature", "-0.1"),
    (["deflate", "--jiggle", "-1", "--out", "{tmp}/r"], "--jiggle", "-1"),
    (["deflate", "--jiggle", "0.9", "--out", "{tmp}/r"], "--jiggle", "0.9"),
    (["deflate", "--smooth-jiggle", "0.2", "--out", "{tmp}/r"], "--smooth-jiggle", "0.2"),
    (["deflate", "--smooth-jiggle", "-0.01", "--out", "{tmp}/r"], "--smooth-jiggle", "-0.01"),
    (["deflate", "--smooth-jiggle", "abc", "--out", "{tmp}/r"], "--smooth-jiggle", "abc"),
    (["deflate", "--smooth-jiggle", "0.01", "--temperature", "0.05", "--out", "{tmp}/r"],
     "--smooth-jiggle", "0.01"),
    (["deflate", "--smooth-jiggle", "0.01", "--jiggle", "0.1", "--out", "{tmp}/r"],
     "--smooth-jiggle", "0.01"),
    (["deflate", "--smooth-jiggle-d", "0.5", "--smooth-jiggle", "0.01", "--out", "{tmp}/r"],
     "--smooth-jiggle-d", "0.5"),
    (["deflate", "--smooth-jiggle-d", "10", "--gamma", "271", "--vertices", "600",
      "--smooth-degree", "8", "--out", "{tmp}/r"], "--smooth-jiggle-d", "10"),
    (["deflate", "--smooth-jiggle-d", "nan", "--out", "{tmp}/r"], "--smooth-jiggle-d", "nan"),
    (["deflate", "--smooth-degree", "8", "--out", "{tmp}/r"], "--smooth-degree", "8"),
    (["deflate", "--smooth-jiggle", "0.01", "--smooth-degree", "1", "--out", "{tmp}/r"],
     "--smooth-degree", "1"),
    (["deflate", "--smooth-jiggle", "0.01", "--smooth-degree", "2.5", "--out", "{tmp}/r"],
     "--smooth-degree", "2.5"),
    (["deflate", "--smooth-jiggle", "0.01", "--smooth-degree", "30", "--out", "{tmp}/r"],
     "--smooth-degree", "30"),
    (["deflate", "--smooth-jiggle", "0.01", "--gamma", "271", "--vertices", "600", "--out",
      "{tmp}/r"], "--smooth-jiggle", "0.01"),
    (["deflate", "--from", "{run}", "--smooth-jiggle", "0.01", "--out", "{tmp}/c"],
     "--smooth-jiggle", "0.01"),
    (["deflate", "--shape-imperfection", "0.2", "--out", "{tmp}/r"], "--shape-imperfection",
     "0.2"),
    (["deflate", "--shape-imperfection", "-1e-3", "--out", "{tmp}/r"], "--shape-imperfection",
     "-1e-3"),
    (["deflate", "--shape-imperfection-d", "0.1", "--shape-imperfection", "0.01", "--out",
      "{tmp}/r"], "--shape-imperfection-d", "0.1"),
    (["deflate", "--shape-imperfection-d", "10", "--gamma", "271", "--vertices", "600",
      "--shape-degree", "8", "--out", "{tmp}/r"], "--shape-imperfection-d", "10"),
    (["deflate", "--shape-degree", "8", "--out", "{tmp}/r"], "--shape-degree", "8"),
    (["deflate", "--shape-imperfection", "0.01", "--shape-degree", "critic", "--out",
      "{tmp}/r"], "--shape-degree", "critic"),
    (["deflate", "--shape-imperfection", "0.05", "--shape-degree", "12", "--out", "{tmp}/r"],
     "--shape-imperfection", "0.05"),
    (["deflate", "--gamma", "2333", "--shape-imperfection-d", "1", "--out", "{tmp}/r"],
     "--shape-imperfection-d", "1"),
    (["refine", "--shape-imperfection", "0.05", "--shape-degree", "12", "--out", "{tmp}/r"],
     "--shape-imperfection", "0.05"),
    (["deflate", "--shape-imperfection", "0.01", "--shape-degree", "1", "--out", "{tmp}/r"],
     "--shape-degree", "1"),
    (["deflate", "--shape-imperfection", "0.01", "--shape-degree", "30", "--out", "{tmp}/r"],
     "--shape-degree", "30"),
    (["deflate", "--shape-imperfection", "0.01", "--gamma", "271", "--vertices", "600",
      "--out", "{tmp}/r"], "--shape-imperfection", "0.01"),
    (["deflate", "--from", "{run}", "--shape-imperfection", "0.01", "--out", "{tmp}/c"],
     "--shape-imperfection", "0.01"),
    (["deflate", "--mesh", os.path.join(os.path.dirname(__file__), "fixtures", "evolver",
                                        "sphere_perturbed.fe"),
      "--shape-imperfection", "0.001", "--shape-degree", "3", "--out", "{tmp}/r"],
     "--shape-imperfection", "0.001"),
    # a spontaneous curvature per vertex (h_zero a vertex attribute): a run from a file has a
    # uniform one, and would drop it
    (["deflate", "--mesh", os.path.join(os.path.dirname(__file__), "fixtures", "evolver",
                                        "dented.fe"), "--out", "{tmp}/r"],
     "--mesh", "varies from vertex to vertex"),
    (["refine", "--shape-imperfection-d", "0", "--shape-degree", "8", "--out", "{tmp}/r"],
     "--shape-degree", "8"),
    (["refine", "--shape-imperfection-d", "3", "--out", "{tmp}/r"], "--shape-imperfection-d",
     "3"),
    (["refine", "--shape-degree", "critic", "--out", "{tmp}/r"], "--shape-degree", "critic"),
    (["refine", "--smooth-degree", "8", "--out", "{tmp}/r"], "--smooth-degree", "8"),
    (["sweep", "--shape-imperfection-d", "0.1", "--shape-imperfection", "0.001", "--out",
      "{tmp}/r"], "--shape-imperfection-d 0.1", "--shape-imperfection (units of R)"),
    (["sweep", "--shape-imperfection-d", "-1", "--out", "{tmp}/r"], "--shape-imperfection-d",
     "-1"),
    (["sweep", "--shape-imperfection-d", "0.1", "--shape-degree", "critical,31", "--out",
      "{tmp}/r"], "--shape-degree", "31"),
    (["sweep", "--shape-imperfection-d", "0.1", "--shape-degree", "critical", "--gamma",
      "29160", "--energy-convention", "paper", "--vertices", "1000", "--out", "{tmp}/r"],
     "--shape-degree critical", "degree L = 19"),
    (["refine", "--shape-imperfection", "0.5", "--out", "{tmp}/r"], "--shape-imperfection",
     "0.5"),
    (["refine", "--shape-imperfection", "0.01", "--shape-degree", "60", "--out", "{tmp}/r"],
     "--shape-degree", "60"),
    (["sweep", "--shape-imperfection", "0.2", "--out", "{tmp}/r"], "--shape-imperfection",
     "0.2"),
    (["sweep", "--shape-degree", "8", "--out", "{tmp}/r"], "--shape-degree", "8"),
    (["deflate", "--max-iter", "0", "--out", "{tmp}/r"], "--max-iter", "0"),
    (["deflate", "--max-iter", "1e9", "--out", "{tmp}/r"], "--max-iter", "1e9"),
    (["deflate", "--max-iter", "10000000", "--out", "{tmp}/r"], "--max-iter", "10000000"),
    (["deflate", "--c0", "-1e3", "--out", "{tmp}/r"], "--c0", "-1e3"),
    (["deflate", "--c0", "1e300", "--out", "{tmp}/r"], "--c0", "1e300"),
    (["deflate", "--c0", "nan", "--out", "{tmp}/r"], "--c0", "nan"),
    (["deflate", "--threads", "100000", "--out", "{tmp}/r"], "--threads", "100000"),
    (["deflate", "--threads", "0", "--out", "{tmp}/r"], "--threads", "0"),
    (["deflate", "--threads", "two", "--out", "{tmp}/r"], "--threads", "two"),
    (["deflate", "--E", "-1", "--sigma", "0.3", "--d", "0.01", "--R", "1", "--out", "{tmp}/r"],
     "--E", "-1"),
    (["deflate", "--E", "1", "--sigma", "0.7", "--d", "0.01", "--R", "1", "--out", "{tmp}/r"],
     "--sigma", "0.7"),
    (["deflate", "--E", "1", "--sigma", "-0.5", "--d", "0.01", "--R", "1", "--out", "{tmp}/r"],
     "--sigma", "-0.5"),
    (["deflate", "--E", "1", "--sigma", "0.3", "--d", "2", "--R", "1", "--out", "{tmp}/r"],
     "--d", "2"),
    (["deflate", "--E", "1", "--sigma", "0.3", "--d", "0", "--R", "1", "--out", "{tmp}/r"],
     "--d", "0"),
    (["deflate", "--E", "1", "--sigma", "0.3", "--d", "0.1", "--R", "-1", "--out", "{tmp}/r"],
     "--R", "-1"),
    (["deflate", "--E", "1", "--sigma", "0.3", "--d", "1e-7", "--R", "1", "--out", "{tmp}/r"],
     "--d", "1e-7"),
    (["deflate", "--method", "nope", "--out", "{tmp}/r"], "--method", "nope"),
    (["deflate", "--bending", "nope", "--out", "{tmp}/r"], "--bending", "nope"),
    (["deflate", "--energy-convention", "quarter", "--out", "{tmp}/r"],
     "--energy-convention", "quarter"),
    (["deflate", "--no-such-option", "3", "--out", "{tmp}/r"], "--no-such-option", "3"),
    (["deflate", "--mesh", "{tmp}/missing.fe", "--out", "{tmp}/r"], "--mesh", "missing.fe"),
    (["deflate", "--mesh", "{empty}", "--out", "{tmp}/r"], "--mesh", "empty"),
    (["deflate", "--out", "{file}/sub"], "--out", "afile.txt/sub"),
    (["deflate", "--out", "{file}"], "--out", "afile.txt"),
    (["deflate", "--out", "{ro}/r"], "--out", "ro/r"),
    (["deflate", "--out", "{tmp}/missing/dir/r"], "--out", "missing/dir/r"),
    (["deflate", "--from", "{tmp}/nothing", "--out", "{tmp}/r"], "--from", "nothing"),
    (["deflate", "--from", "{run}"], "--from", "run"),
    (["deflate", "--from", "{run}", "--gamma", "300", "--out", "{tmp}/r"], "--gamma", "300"),
    (["deflate", "--from", "{run}", "--step", "99", "--out", "{tmp}/r"], "--step", "99"),
    (["deflate", "--from", "{run}", "--dv", "nan", "--out", "{tmp}/r"], "--dv", "nan"),
    (["deflate", "--from", "{run}", "--until", "1.5", "--out", "{tmp}/r"], "--until", "1.5"),
    # continue
    (["continue", "{run}", "--then-deflate-to", "2", "--gamma", "300", "--increments", "2",
      "--out", "{tmp}/c"], "--then-deflate-to", "2"),
    (["continue", "{run}", "--gamma", "300", "--increments", "2", "--compare", "{tmp}/nonexistent",
      "--out", "{tmp}/c"], "--compare", "nonexistent"),
    (["continue", "{run}", "--compare", "{run}", "--compare-step", "42", "--out", "{tmp}/c"],
     "--compare-step", "42"),
    (["continue", "{run}", "--dv", "nan", "--out", "{tmp}/c"], "--dv", "nan"),
    (["continue", "{run}", "--dv", "0", "--out", "{tmp}/c"], "--dv", "0"),
    (["continue", "{run}", "--dv", "0.7", "--out", "{tmp}/c"], "--dv", "0.7"),
    (["continue", "{run}", "--dv", "1e-9", "--until", "0.9", "--out", "{tmp}/c"], "--dv",
     "1e-9"),
    (["continue", "{run}", "--until", "1.5", "--out", "{tmp}/c"], "--until", "1.5"),
    (["continue", "{run}", "--until", "0.01", "--out", "{tmp}/c"], "--until", "0.01"),
    (["continue", "{run}", "--schedule", "garbage", "--out", "{tmp}/c"], "--schedule",
     "garbage"),
    (["continue", "{run}", "--schedule", "0.1,1.2", "--out", "{tmp}/c"], "--schedule", "1.2"),
    (["continue", "{run}", "--increments", "100000000", "--gamma", "300", "--out", "{tmp}/c"],
     "--increments", "100000000"),
    (["continue", "{run}", "--increments", "-1", "--gamma", "300", "--out", "{tmp}/c"],
     "--increments", "-1"),
    (["continue", "{run}", "--gamma", "1e300", "--increments", "2", "--out", "{tmp}/c"],
     "--gamma", "1e300"),
    (["continue", "{run}", "--gamma", "-1e3", "--increments", "2", "--out", "{tmp}/c"],
     "--gamma", "-1e3"),
    (["continue", "{run}", "--gamma", "1e6", "--increments", "2", "--out", "{tmp}/c"],
     "--gamma", "1e6"),
    (["continue", "{run}", "--gamma", "300,nan", "--out", "{tmp}/c"], "--gamma", "300,nan"),
    (["continue", "{run}", "--gamma", "garbage", "--increments", "2", "--out", "{tmp}/c"],
     "--gamma", "garbage"),
    (["continue", "{run}", "--c0", "-1e3", "--increments", "2", "--out", "{tmp}/c"], "--c0",
     "-1e3"),
    (["continue", "{run}", "--c0", "inf", "--increments", "2", "--out", "{tmp}/c"], "--c0",
     "inf"),
    (["continue", "{run}", "--step", "99", "--out", "{tmp}/c"], "--step", "99"),
    (["continue", "{run}", "--step", "x", "--out", "{tmp}/c"], "--step", "x"),
    (["continue", "{run}", "--seed", "-3", "--out", "{tmp}/c"], "--seed", "-3"),
    (["continue", "{run}", "--temperature", "5", "--out", "{tmp}/c"], "--temperature", "5"),
    (["continue", "{run}", "--out", "{file}/sub"], "--out", "afile.txt/sub"),
    (["continue", "{run}", "--out", "{ro}/c"], "--out", "ro/c"),
    (["continue", "{run}", "--out", "{tmp}/missing/c"], "--out", "missing/c"),
    (["continue", "{tmp}/nothing", "--out", "{tmp}/c"], "DIR", "nothing"),
    (["continue", "{file}", "--out", "{tmp}/c"], "DIR", "afile.txt"),
    (["continue", "{run}", "--gamma", "300", "--increments", "2", "--then-deflate-to", "0.5",
      "--then-out", "{file}/x", "--out", "{tmp}/c"], "--then-out", "afile.txt/x"),
    # analyze classify export table view resume evolver-energy
    (["analyze", "{tmp}/nothing"], "DIR", "nothing"),
    (["analyze", "{file}"], "DIR", "afile.txt"),
    (["analyze", "{empty}"], "DIR", "empty"),
    (["classify", "{tmp}/nothing.vtk"], "FILE", "nothing.vtk"),
    (["classify", "{run}", "--step", "99"], "--step", "99"),
    (["classify", "{run}", "--step", "1e3"], "--step", "1e3"),
    (["classify", "{empty}"], "FILE", "empty"),
    (["export", "{run}", "--step", "99", "--format", "vtk", "--out", "{tmp}/x.vtk"], "--step",
     "99"),
    (["export", "{run}", "--step", "-1", "--format", "gif", "--out", "{tmp}/x.gif"], "--format",
     "gif"),
    (["export", "{run}", "--step", "-1", "--format", "vtk", "--out", "{empty}"], "--out",
     "empty"),
    (["export", "{run}", "--step", "-1", "--format", "vtk", "--out", "{file}/x.vtk"], "--out",
     "afile.txt/x.vtk"),
    (["export", "{run}", "--step", "-1", "--format", "vtk", "--out", "{ro}/x.vtk"], "--out",
     "ro/x.vtk"),
    (["export", "{run}", "--step", "-1", "--format", "vtk", "--out", "{tmp}/no/x.vtk"], "--out",
     "no/x.vtk"),
    (["export", "{tmp}/nothing", "--step", "-1", "--format", "vtk"], "DIR", "nothing"),
    (["export", "{run}", "--step", "last", "--format", "vtk"], "--step", "last"),
    (["table", "{tmp}/nothing"], "DIR", "nothing"),
    (["table", "{file}"], "DIR", "afile.txt"),
    (["table", "{full}"], "DIR", "full"),
    (["view", "{run}", "--out", "{empty}"], "--out", "empty"),
    (["view", "{run}", "--out", "{tmp}/no/v.html"], "--out", "no/v.html"),
    (["view", "{run}", "--out", "{ro}/v.html"], "--out", "ro/v.html"),
    (["view", "{run}", "--out", "{tmp}/v.png"], "--out", "v.png"),
    (["view", "{run}", "--color", "purple", "--out", "{tmp}/v.html"], "--color", "purple"),
    (["view", "{tmp}/nothing"], "DIR", "nothing"),
    (["resume", "{tmp}/nothing"], "DIR", "nothing"),
    (["resume", "{run}", "--threads", "100000"], "--threads", "100000"),
    (["resume", "{run}", "--threads", "-2"], "--threads", "-2"),
    (["evolver-energy", "{empty}"], "FILE", "empty"),
    (["evolver-energy", "{tmp}/nothing.fe"], "FILE", "nothing.fe"),
    # plot report
    (["plot", "{run}", "--dpi", "1000000", "--out", "{tmp}/f"], "--dpi", "1000000"),
    (["plot", "{run}", "--dpi", "10", "--out", "{tmp}/f"], "--dpi", "10"),
    (["plot", "{run}", "--dpi", "high", "--out", "{tmp}/f"], "--dpi", "high"),
    (["plot", "{run}", "--at", "1.5", "--out", "{tmp}/f"], "--at", "1.5"),
    (["plot", "{run}", "--at", "nan", "--out", "{tmp}/f"], "--at", "nan"),
    (["plot", "{run}", "--every", "0", "--out", "{tmp}/f"], "--every", "0"),
    (["plot", "{run}", "--format", "gif", "--out", "{tmp}/f"], "--format", "gif"),
    (["plot", "{run}", "--out", "{file}"], "--out", "afile.txt"),
    (["plot", "{run}", "--out", "{ro}/f"], "--out", "ro/f"),
    (["plot", "{run}", "--out", "{tmp}/no/f"], "--out", "no/f"),
    (["plot", "{tmp}/nothing", "--out", "{tmp}/f"], "DIR", "nothing"),
    (["plot", "--pair", "{run}", "{tmp}/nothing", "--out", "{tmp}/f"], "--pair", "nothing"),
    (["plot", "{run}", "--reference", "{empty}", "--out", "{tmp}/f"], "--reference", "empty"),
    (["report", "{tmp}/nothing", "--out", "{tmp}/r.md"], "DIR", "nothing"),
    (["report", "{full}", "--out", "{tmp}/r.md"], "DIR", "full"),
    (["report", "{run}", "--out", "{tmp}/missing/dir/r.md"], "--out", "missing/dir/r.md"),
    (["report", "{run}", "--out", "{empty}"], "--out", "empty"),
    (["report", "{run}", "--out", "{ro}/r.md"], "--out", "ro/r.md"),
    (["report", "{run}", "--out", "{file}/r.md"], "--out", "afile.txt/r.md"),
    (["report", "{run}", "--format", "pdf", "--out", "{tmp}/r.md"], "--format", "pdf"),
    (["report", "{run}", "--reference", "{tmp}/no.json", "--out", "{tmp}/r.md"], "--reference",
     "no.json"),
    # never a file of a run's store, nor one written beside the output (an XDMF file's .h5)
    (["report", "{run}", "--out", "{run}/run.json", "--no-figures"], "--out", "run/run.json"),
    (["report", "{run}", "--out", "{tmp}/r.pdf", "--no-figures"], "--out", "r.pdf"),
    (["report", "{run}", "--format", "html", "--out", "{tmp}/r.md"], "--out", "r.md"),
    (["report", "{run}", "--out", "{run}/steps/r.md", "--no-figures"], "--out",
     "run/steps/r.md"),
    (["export", "{run}", "--format", "xdmf", "--out", "{run}/mesh.xdmf"], "--out",
     "run/mesh.xdmf"),
    (["export", "{run}", "--format", "xdmf", "--out", "{run}/steps/step_000001.xdmf"],
     "--out", "run/steps/step_000001.xdmf"),
    (["export", "{run}", "--step", "-1", "--format", "vtk", "--out", "{run}/steps/s.vtk"],
     "--out", "run/steps/s.vtk"),
    (["plot", "{run}", "--out", "{run}/steps"], "--out", "run/steps"),
    (["export", "{run}", "--format", "xdmf", "--out", "{link}/step_000001.xdmf"], "--out",
     "steps_link/step_000001.xdmf"),
    (["continue", "{run}", "--gamma", "300", "--out", "{run}/steps/b"], "--out",
     "run/steps/b"),
    # reproduce-paper
    (["reproduce-paper", "--out", "{run}"], "--out", "run"),
    (["reproduce-paper", "--out", "{full}"], "--out", "full"),
    (["reproduce-paper", "--out", "{file}"], "--out", "afile.txt"),
    (["reproduce-paper", "--out", "{ro}/s"], "--out", "ro/s"),
    (["reproduce-paper", "--out", "{tmp}/no/s"], "--out", "no/s"),
    (["reproduce-paper", "--gammas", "271,-5", "--out", "{tmp}/s"], "--gammas", "-5"),
    (["reproduce-paper", "--gammas", "1e300", "--out", "{tmp}/s"], "--gammas", "1e300"),
    (["reproduce-paper", "--gammas", "abc", "--out", "{tmp}/s"], "--gammas", "abc"),
    (["reproduce-paper", "--gammas", "2e7", "--out", "{tmp}/s"], "--gammas", "2e7"),
    (["reproduce-paper", "--seeds", "0", "--out", "{tmp}/s"], "--seeds", "0"),
    (["reproduce-paper", "--seeds", "100000", "--out", "{tmp}/s"], "--seeds", "100000"),
    (["reproduce-paper", "--vertices", "5", "--out", "{tmp}/s"], "--vertices", "5"),
    (["reproduce-paper", "--vertices", "3594", "10000000000", "--out", "{tmp}/s"], "--vertices",
     "10000000000"),
    (["reproduce-paper", "--vertices", "100", "--out", "{tmp}/s"], "--vertices", "100"),
    (["reproduce-paper", "--until", "1.5", "--out", "{tmp}/s"], "--until", "1.5"),
    (["reproduce-paper", "--until", "-0.5", "--out", "{tmp}/s"], "--until", "-0.5"),
    (["reproduce-paper", "--dv", "nan", "--out", "{tmp}/s"], "--dv", "nan"),
    (["reproduce-paper", "--path-increments", "0", "--out", "{tmp}/s"], "--path-increments",
     "0"),
    (["reproduce-paper", "--path-increments", "100000000", "--out", "{tmp}/s"],
     "--path-increments", "100000000"),
    (["reproduce-paper", "--workers", "0", "--out", "{tmp}/s"], "--workers", "0"),
    (["reproduce-paper", "--workers", "100000", "--out", "{tmp}/s"], "--workers", "100000"),
    (["reproduce-paper", "--formats", "gif", "--out", "{tmp}/s"], "--formats", "gif"),
    (["reproduce-paper", "--compare-conventions", "--sensitivity", "0", "--out", "{tmp}/s"],
     "--sensitivity", "0"),
    # sweep
    (["sweep", "--config", "{empty}", "--out", "{tmp}/w"], "--config", "empty"),
    (["sweep", "--config", "{tmp}/no.toml", "--out", "{tmp}/w"], "--config", "no.toml"),
    (["sweep", "--gamma", "271,1e300", "--out", "{tmp}/w"], "--gamma", "1e300"),
    (["sweep", "--gamma", "271,abc", "--out", "{tmp}/w"], "--gamma", "abc"),
    (["sweep", "--gamma", "1e7", "--out", "{tmp}/w"], "--gamma", "1e7"),
    (["sweep", "--nu", "0.5", "--out", "{tmp}/w"], "--nu", "0.5"),
    (["sweep", "--seeds", "0-99999999999", "--out", "{tmp}/w"], "--seeds", "0-99999999999"),
    (["sweep", "--seeds", "-1", "--out", "{tmp}/w"], "--seeds", "-1"),
    (["sweep", "--vertices", "10000000000", "--out", "{tmp}/w"], "--vertices", "10000000000"),
    (["sweep", "--icosphere", "100000", "--out", "{tmp}/w"], "--icosphere", "100000"),
    (["sweep", "--dv", "nan", "--out", "{tmp}/w"], "--dv", "nan"),
    (["sweep", "--until", "1.5", "--out", "{tmp}/w"], "--until", "1.5"),
    (["sweep", "--jiggle", "3", "--out", "{tmp}/w"], "--jiggle", "3"),
    (["sweep", "--workers", "100000", "--out", "{tmp}/w"], "--workers", "100000"),
    (["sweep", "--workers", "zero", "--out", "{tmp}/w"], "--workers", "zero"),
    (["sweep", "--out", "{run}"], "--out", "run"),
    (["sweep", "--out", "{file}"], "--out", "afile.txt"),
    (["sweep", "--out", "{tmp}/no/w"], "--out", "no/w"),
    (["sweep", "--out", "{ro}/w"], "--out", "ro/w"),
    # theory
    (["theory", "--out", "{empty}"], "--out", "empty"),
    (["theory", "--out", "{tmp}/no/t.png"], "--out", "no/t.png"),
    (["theory", "--out", "{tmp}/t.txt"], "--out", "t.txt"),
    (["theory", "--out", "{ro}/t.png"], "--out", "ro/t.png"),
    (["theory", "--out", "{file}/t.png"], "--out", "afile.txt/t.png"),
    (["theory", "--energy-convention", "quarter"], "--energy-convention", "quarter"),
]


def _fill(argv, places, tmp):
    names = {k: v for k, v in places.items() if k != "root"} | {"tmp": str(tmp)}
    return [a.format(**names) for a in argv]


def _listing(*folders) -> set:
    return {os.path.join(d, f) for folder in folders for d, subs, files in os.walk(folder)
            for f in subs + files}


def _refused(argv, capsys) -> tuple[int, str]:
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's errors
        code = exc.code
    return code, capsys.readouterr().err


def test_at_least_150_cases_across_every_command():
    commands = {argv[0] for argv, _, _ in CASES}
    assert len(CASES) >= 150
    assert commands == {"analyze", "classify", "continue", "deflate", "evolver-energy",
                        "export", "plot", "refine", "report", "reproduce-paper", "resume", "sweep",
                        "table", "theory", "view"}


_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
_READ_ONLY = pytest.mark.skipif(_ROOT, reason="a read-only folder is writable by root")


@pytest.mark.parametrize("argv, option, value", [
    pytest.param(*case, marks=[_READ_ONLY] if any("{ro}" in a for a in case[0]) else [],
                 id=" ".join(case[0])[:70]) for case in CASES])
def test_bad_input_is_refused_in_one_line_before_any_work(places, tmp_path, monkeypatch, capsys,
                                                          argv, option, value):
    monkeypatch.chdir(tmp_path)
    before = _listing(tmp_path, places["root"])
    code, err = _refused(_fill(argv, places, tmp_path), capsys)
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"shellbuckle {argv[0]}: error: ")
    assert option in lines[0] and value in lines[0], lines[0]
    assert "np.float64" not in lines[0]
    assert _listing(tmp_path, places["root"]) == before, "nothing is written for refused input"


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
@pytest.mark.parametrize("argv", [
    ["deflate", "--out", "/proc/shellbuckle_run"],
    ["sweep", "--out", "/proc/shellbuckle_sweep"],
    ["theory", "--out", "/proc/shellbuckle.png"],
    ["deflate", "--out", "/proc"],
])
@pytest.mark.parametrize("probe", ["nameless", "named"])
def test_a_folder_the_file_system_refuses_is_refused_before_any_work(tmp_path, monkeypatch,
                                                                       capsys, argv, probe):
    # /proc refuses new files whoever asks; os.access says yes, as it does to the superuser
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(os, "access", lambda *args, **kwargs: True)
    if probe == "named":  # a file system without nameless files (O_TMPFILE)
        monkeypatch.delattr(os, "O_TMPFILE", raising=False)
    code, err = _refused(argv, capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"shellbuckle {argv[0]}: error: --out {argv[-1]}: ")
    assert "not writable" in lines[0]
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("probe", ["nameless", "named"])
def test_the_writability_probe_leaves_nothing_in_a_writable_folder(tmp_path, monkeypatch, probe):
    from shellbuckle.commands._checks import output_file, output_folder

    if probe == "named":
        monkeypatch.delattr(os, "O_TMPFILE", raising=False)
    folder = tmp_path / "here"
    folder.mkdir()
    assert output_folder("--out", folder) == folder
    assert output_folder("--out", folder / "new") == folder / "new"
    assert output_file("--out", folder / "f.png", (".png",)) == folder / "f.png"
    assert list(folder.iterdir()) == []


@pytest.mark.parametrize("argv, option, value", [
    (["deflate", "--gamma", "-1e3", "--out", "x"], "--gamma", "-1e3"),
    (["deflate", "--vertices", "200", "--pressures", "1e4", "--out", "x"], "--pressures", "1e4"),
    (["deflate", "--bogus"], "--bogus", "--bogus"),
    (["theory", "--gamma", "1e-300"], "--gamma", "1e-300"),
])
def test_the_real_exit_code_is_2(tmp_path, argv, option, value):
    done = subprocess.run([sys.executable, "-m", "shellbuckle.cli", *argv], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1 and option in done.stderr
    assert value in done.stderr and "Traceback" not in done.stderr
    assert not any(tmp_path.iterdir())


# --------------------------------------------------------------------------- valid edges

@pytest.mark.parametrize("argv, dest, expected", [
    (["deflate", "--c0", "-1e3"], "c0", -1e3),
    (["deflate", "--c0=-1e3"], "c0", -1e3),
    (["deflate", "--dv", "-0.019"], "dv", -0.019),
    (["deflate", "--dv", "-.5"], "dv", -0.5),
    (["deflate", "--gamma", "1"], "gamma", 1.0),
    (["deflate", "--gamma", "1e11"], "gamma", 1e11),
    (["deflate", "--nu", "-0.99"], "nu", -0.99),
    (["deflate", "--nu", "0.49"], "nu", 0.49),
    (["deflate", "--vertices", str(MIN_VERTICES)], "vertices", MIN_VERTICES),
    (["deflate", "--vertices", str(MAX_VERTICES)], "vertices", MAX_VERTICES),
    (["deflate", "--icosphere", "316"], "icosphere", 316),
    (["deflate", "--until", "0.98"], "until", 0.98),
    (["deflate", "--temperature", "0"], "temperature", 0.0),
    (["deflate", "--temperature", "1"], "temperature", 1.0),
    (["deflate", "--jiggle", "0.5"], "jiggle", 0.5),
    (["deflate", "--smooth-jiggle", "0.1"], "smooth_jiggle", 0.1),
    (["deflate", "--smooth-jiggle", "0"], "smooth_jiggle", 0.0),
    (["deflate", "--smooth-degree", "400"], "smooth_degree", 400),
    (["deflate", "--seed", "4294967295"], "seed", 4294967295),
    (["deflate", "--threads", "1"], "threads", 1),
    (["continue", "DIR", "--c0", "-1e3", "--out", "o"], "c0", "-1e3"),
    (["continue", "DIR", "--c0", "-1:2", "--out", "o"], "c0", "-1:2"),
    (["continue", "DIR", "--gamma", "-1e3", "--out", "o"], "gamma", "-1e3"),
    (["continue", "DIR", "--step", "-2", "--out", "o"], "step", -2),
    (["continue", "DIR", "--increments", "0", "--out", "o"], "increments", 0),
    (["plot", "--dpi", "50"], "dpi", 50),
    (["plot", "--dpi", "1200"], "dpi", 1200),
    (["plot", "--at", "0"], "at", 0.0),
    (["theory", "--gamma", "1e11"], "gamma", 1e11),
])
def test_edge_values_parse(argv, dest, expected):
    assert getattr(build_parser().parse_args(argv), dest) == expected


def test_valid_edges_of_cheap_commands_run(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for gamma, nu in (("1", "-0.99"), ("1e11", "0.49")):
        assert main(["theory", "--gamma", gamma, "--nu", nu, "--out", "t.pdf", "--json"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning") == 1 and len(err.strip().splitlines()) == 1  # nu > 1/3
    assert (tmp_path / "t.pdf").exists()


def test_theory_prints_the_file_it_wrote(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["theory", "--out", "t.png"]) == 0
    assert capsys.readouterr().out.strip().endswith("figure: t.png")
    assert (tmp_path / "t.png").exists()


def test_the_mesh_rule():
    # a mean edge of pi l_el at most: N >= 8 sqrt(gamma)/(sqrt(3) pi) + 2
    assert vertices_needed(15163.0) == 184
    assert vertices_needed(gamma_resolved(400)) <= 401
    assert vertices_needed(29160.0) <= 3594   # the paper's largest gamma on its mesh
    assert vertices_needed(4 * 15163.0) <= 400  # the quick study under the paper's reading


def test_the_smooth_degree_rule():
    # 4 mean edges per shortest wavelength 2 pi R/L of the smooth imperfection
    from shellbuckle.protocol.imperfection import DEFAULT_DEGREE

    for n in (600, 3594, 40000, MAX_VERTICES):
        L = degree_resolved(n)
        assert 2 * math.pi / L >= 4 * mean_edge(n) > 2 * math.pi / (L + 1)
    assert degree_resolved(3594) >= DEFAULT_DEGREE  # the paper's mesh resolves the default
    assert degree_resolved(MAX_VERTICES) >= 400  # the largest degree allowed


def test_a_sweeps_help_states_the_ranges_its_lists_are_checked_against():
    from shellbuckle.commands._checks import RANGES
    from shellbuckle.commands.sweep import SPANS

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    sweep = sub.choices["sweep"]
    helps = {a.dest: " ".join((a.help or "").replace("%%", "%").split())
             for a in sweep._actions}
    for axis, span in SPANS.items():
        assert f"allowed: {RANGES[span].explained()}" in helps[axis], (axis, helps[axis])


@pytest.mark.parametrize("typed", ["critic", "31", "1"])
def test_deflate_and_sweep_refuse_a_shape_degree_alike(typed, tmp_path, capsys):
    """One declaration of ``--shape-degree`` (an integer in range, or ``critical``): a single
    degree of ``deflate`` and an item of a sweep's list are refused with the same reason."""
    reasons = []
    for command in ("deflate", "sweep"):
        try:
            code = main([command, "--shape-imperfection-d", "0.1", "--shape-degree", typed,
                         "--out", str(tmp_path / command)])
        except SystemExit as exit_:
            code = exit_.code
        assert code == 2
        line = capsys.readouterr().err.strip().splitlines()[-1]
        assert "'critical' (the shell's buckling degree + 1)" in line
        reasons.append(line.split("allowed:", 1)[1])
        assert not (tmp_path / command).exists()
    assert reasons[0] == reasons[1]
