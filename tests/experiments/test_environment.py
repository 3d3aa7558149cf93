"""``jaxtrack.experiments.common.environment``: what the experiments' records say produced
their numbers (commit and package versions), so that a table that does not reproduce can be
traced to a code or an environment change."""

from __future__ import annotations

import platform
import shutil
import subprocess

import cv2
import jax
import numpy as np
import pytest

from jaxtrack.experiments.common import (
    ENVIRONMENT_PACKAGES,
    checkout_commit,
    environment,
    environment_line,
    environment_lines,
)

needs_git = pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")


def _git(folder, *args) -> str:
    env = {
        "GIT_AUTHOR_NAME": "t",
        "GIT_AUTHOR_EMAIL": "t@example.org",
        "GIT_COMMITTER_NAME": "t",
        "GIT_COMMITTER_EMAIL": "t@example.org",
        "HOME": str(folder),
        "PATH": "/usr/bin:/bin:/usr/local/bin",
    }
    done = subprocess.run(
        ["git", "-C", str(folder), *args], capture_output=True, text=True, env=env, check=True
    )
    return done.stdout.strip()


def test_versions_are_those_of_the_running_packages():
    found = environment()
    assert list(found) == ["jaxtrack_commit", "python", *ENVIRONMENT_PACKAGES, "opencv"]
    assert found["jax"] == jax.__version__ and found["numpy"] == np.__version__
    assert found["opencv"] == cv2.__version__
    assert found["python"] == platform.python_version()


def test_no_commit_outside_a_git_checkout(tmp_path):
    assert checkout_commit(tmp_path) is None


@needs_git
def test_commit_and_changes_of_a_checkout(tmp_path):
    _git(tmp_path, "init", "-q")
    (tmp_path / "a.txt").write_text("one\n")
    _git(tmp_path, "add", "a.txt")
    _git(tmp_path, "commit", "-q", "-m", "first")
    head = _git(tmp_path, "rev-parse", "--short=12", "HEAD")
    assert checkout_commit(tmp_path) == head
    (tmp_path / "b.txt").write_text("untracked\n")  # not part of the code: no change
    assert checkout_commit(tmp_path) == head
    (tmp_path / "a.txt").write_text("two\n")
    assert checkout_commit(tmp_path) == f"{head}+changes"


def test_the_line_names_the_commit_and_every_version():
    found = {"jaxtrack_commit": "abc123", "python": "3.11.7", "jax": "0.10.2", "opencv": "5.1.0"}
    line = environment_line(found)
    assert line == "Environment: jaxtrack commit abc123; python 3.11.7, jax 0.10.2, opencv 5.1.0."
    assert "commit unknown" in environment_line({**found, "jaxtrack_commit": None})
    assert environment_lines({"environment": found}) == [line]
    assert environment_lines({}) == []
