"""The DDS domain reservation's lock files in a shared /tmp: never followed through a planted link."""

from __future__ import annotations

import os

import pytest

from mbctl.unitree import domain_lock
from mbctl.unitree.domain_lock import lock_path, reserve_domain
from mbctl.unitree.exceptions import ChannelError


@pytest.fixture
def lock_dir(tmp_path, monkeypatch):
    monkeypatch.setattr(domain_lock, "LOCK_DIR", str(tmp_path))
    return tmp_path


def test_a_planted_dangling_symlink_is_refused_and_nothing_is_created_through_it(lock_dir):
    target = lock_dir / "elsewhere" / "victim"
    (lock_dir / "elsewhere").mkdir()
    os.symlink(target, lock_path(7))
    with pytest.raises(ChannelError, match=r"the DDS domain lock '.*/mbctl-dds-7\.lock' is a symbolic link "
                                           r"\(to '.*/elsewhere/victim'\); refusing to follow it"):
        with reserve_domain(7):
            pass
    assert not target.exists()  # O_CREAT through the link would have made it


def test_a_symlink_to_an_existing_file_is_refused_too(lock_dir):
    target = lock_dir / "someone_s_file"
    target.write_text("keep")
    os.symlink(target, lock_path(8))
    with pytest.raises(ChannelError, match="is a symbolic link"):
        with reserve_domain(8):
            pass
    assert target.read_text() == "keep"


def test_a_fifo_at_the_path_is_refused_not_waited_on(lock_dir):
    os.mkfifo(lock_path(9))
    with pytest.raises(ChannelError, match=r"mbctl-dds-9\.lock' is not a regular file"):
        with reserve_domain(9):
            pass


def test_a_regular_lock_file_is_made_and_locked_and_not_inherited(lock_dir):
    with reserve_domain(11) as domain:
        assert domain == 11 and os.path.isfile(lock_path(11)) and not os.path.islink(lock_path(11))
        fds = [int(fd) for fd in os.listdir("/proc/self/fd")
               if os.path.realpath(f"/proc/self/fd/{fd}") == os.path.realpath(lock_path(11))]
        assert len(fds) == 1 and not os.get_inheritable(fds[0])
