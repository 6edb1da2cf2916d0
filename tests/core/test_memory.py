"""The allocator policy: set once, for this process and the processes it starts."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

from microfab.core.memory import ALLOCATOR_SETTINGS, apply_allocator_policy


def test_the_policy_is_set_for_this_process_and_its_children():
    code = (
        "import os, sys; from microfab.core.memory import apply_allocator_policy as a;"
        "ok = a(); print(ok, *(os.environ[k] for k in sys.argv[1:]))"
    )
    names = [env for _, env, _ in ALLOCATOR_SETTINGS]
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    out = subprocess.run([sys.executable, "-c", code, *names], env=env, check=True,
                         capture_output=True, text=True).stdout.split()  # fmt: skip
    expected = [str(v) for _, _, v in ALLOCATOR_SETTINGS]
    if platform.libc_ver()[0] == "glibc":
        assert out[0] == "True"  # mallopt accepted every setting
    assert out[1:] == expected  # exported for the processes it starts


def test_a_users_own_setting_wins_and_a_second_call_is_cheap(monkeypatch):
    monkeypatch.setenv("MALLOC_TOP_PAD_", "12345")
    apply_allocator_policy()
    assert os.environ["MALLOC_TOP_PAD_"] == "12345"
    assert apply_allocator_policy() in (True, False)
