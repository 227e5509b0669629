"""Build hook: a wheel built from a git checkout records the commit it was built from.

``pip install .`` copies the package without its ``.git``; the run store then has no commit
to write into ``run.json`` (:func:`shellbuckle.store.meta.source_commit`). This hook writes
``shellbuckle/_build.json`` (the commit, ``+dirty`` if the package's files differed from it)
into the built package. An editable install reads the checkout itself and gets no file.
Everything else is declared in ``pyproject.toml``.
"""

import json
import subprocess
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent


def _commit():
    """This checkout's commit (``+dirty`` if the package's files differ from it); None where
    git cannot tell, or where the package is not tracked here (an unpacked archive inside
    some other repository)."""
    git = ["git", "--no-optional-locks", "-C", str(HERE)]
    try:
        tracked = subprocess.run(git + ["ls-files", "--", "src/shellbuckle/__init__.py"],
                                 capture_output=True, text=True, timeout=10,
                                 check=True).stdout.strip()
        if not tracked:
            return None
        commit = subprocess.run(git + ["rev-parse", "--short=12", "HEAD"], capture_output=True,
                                text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(git + ["status", "--porcelain", "--", "src/shellbuckle"],
                               capture_output=True, text=True, timeout=10,
                               check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return (f"{commit}+dirty" if dirty else commit) or None


class BuildWithCommit(build_py):
    def run(self):
        super().run()
        target = Path(self.build_lib) / "shellbuckle" / "_build.json"
        commit = None if getattr(self, "editable_mode", False) else _commit()
        if commit:
            target.write_text(json.dumps({"git": commit}) + "\n", encoding="utf-8")
        else:  # never a commit left there by an earlier build of the same tree
            target.unlink(missing_ok=True)


setup(cmdclass={"build_py": BuildWithCommit})
