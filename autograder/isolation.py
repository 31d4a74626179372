"""Root-only machinery of the sandbox: a dedicated uid per worker slot, a staged copy of
what the child imports, the reference made unreadable, and clean-up after each check.

Used by :class:`autograder.sandbox.Session` when the grader runs as root (Gradescope,
CI). Each worker slot gets its own unprivileged uid and gid (no supplementary groups)
from a high range that no account uses, locked with ``flock`` so that two grading runs
on one machine never share one. The child of a check:

* runs in a private working directory owned by its uid, inside root-owned 0711
  directories, and imports ``course/``, the runner and tasks of ``autograder/`` and the
  implementation from a root-owned staging copy (:func:`stage`), never from the
  repository;
* cannot read the reference: :func:`protect_reference` makes ``solutions/``,
  ``autograder/mistakes/`` and every module whose first lines hold ``# RELEASE: omit``
  unreadable by others (the session's notice says so);
* cannot write the grader, the Python installation or the parent's files (all
  root-owned); its stdout and stderr go to files in a root-only directory;
* is limited to :data:`PROCESSES` processes and threads (RLIMIT_NPROC of its uid);
* is gone after the check, with everything it started: :func:`kill_uid` signals every
  process of the uid (``kill(-1, SIGKILL)`` from a helper that has the uid), the session
  is a child subreaper so that orphans are reaped, and files the uid left in the shared
  temporary directories are removed (:func:`sweep_temp`).

Memory across the child's whole process tree is bounded by :class:`MemoryWatch`, a
thread of the parent that sums the proportional set size (PSS, else RSS) of each slot's
uid from ``/proc`` every 50 ms and kills the uid's processes when the sum exceeds the
limit. (cgroup v2 would be more exact, but needs a delegated, writable hierarchy that
containers such as Gradescope's rarely give; the watchdog works everywhere.) The
per-process RLIMIT_AS, CPU and file-size limits stay as they were (:mod:`autograder.child`).
"""

import fcntl
import grp
import os
import pwd
import shutil
import signal
import stat
import sys
import sysconfig
import tempfile
import threading
import time
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
#: first uid/gid tried for the slots (Debian leaves 60000-64999 to packages that are
#: rarely installed; ids that an account or group uses are skipped); ``AUTOGRADER_FIRST_ID``
#: moves the range, e.g. for graders on one machine that must not see each other's children
FIRST_ID = int(os.environ.get("AUTOGRADER_FIRST_ID", "61700"))
ID_RANGE = 200
#: RLIMIT_NPROC of a child's uid: its processes and threads (BLAS runs one thread)
PROCESSES = 32
#: what the child imports from the repository, staged for it: files and packages of ``autograder/``
AUTOGRADER_FILES = ("__init__.py", "child.py", "forkserver.py")
AUTOGRADER_PACKAGES = ("tasks",)
OMIT_MARKER = "# RELEASE: omit"
TEMP_DIRS = ("/tmp", "/var/tmp", "/dev/shm")
LIBRARY_SKIP = {"site-packages", "dist-packages", "test", "idlelib", "turtledemo", "ensurepip",
                "tkinter", "__phello__"}


class IsolationError(RuntimeError):
    """The grader runs as root but cannot give the children a uid of their own safely."""


def is_root() -> bool:
    return hasattr(os, "geteuid") and os.geteuid() == 0


# ---------------------------------------------------------------- what others may read


def _other_can(path, bits) -> bool:
    try:
        st = os.stat(path)
    except OSError:
        return False
    return (st.st_mode & bits) == bits


def unreachable(path, *, read=True, execute=False) -> str:
    """Why a user with no relation to the owners cannot reach ``path`` ('' when they can).

    Every directory above needs o+x; the path itself o+r (o+rx for a directory or with
    ``execute``). Only the permission bits are read (ACLs are not considered).
    """
    path = os.path.realpath(path)
    parts = Path(path).parents
    for parent in reversed(list(parts)):
        if not _other_can(parent, stat.S_IXOTH):
            return f"{parent} is not searchable by other users ({_mode(parent)})"
    try:
        st = os.stat(path)
    except OSError as exc:
        return f"{path}: {exc.strerror}"
    need = (stat.S_IROTH if read else 0) | (stat.S_IXOTH if execute or stat.S_ISDIR(st.st_mode) else 0)
    if st.st_mode & need != need:
        return f"{path} is not readable by other users ({_mode(path)})"
    return ""


def _mode(path) -> str:
    try:
        return stat.filemode(os.stat(path).st_mode)
    except OSError:
        return "?"


def python_problems():
    """``(interpreter, packages)``: why the child's uid cannot run this Python, and why it
    cannot import its installed packages (each a list of reasons, empty when fine)."""
    interpreter = []
    why = unreachable(sys.executable, execute=True)
    if why:
        interpreter.append(why)
    paths = sysconfig.get_paths()
    for key in ("stdlib", "platstdlib"):
        why = unreachable(paths[key])
        if why and why not in interpreter:
            interpreter.append(why)
    dynload = os.path.join(paths["platstdlib"], "lib-dynload")
    if os.path.isdir(dynload):
        why = unreachable(dynload)
        if why and why not in interpreter:
            interpreter.append(why)
    packages = []
    for directory in site_packages():
        why = unreachable(directory)
        if why:
            packages.append(why)
            continue
        for entry in os.scandir(directory):
            try:
                mode = entry.stat(follow_symlinks=True).st_mode
            except OSError:
                continue
            need = stat.S_IROTH | (stat.S_IXOTH if stat.S_ISDIR(mode) else 0)
            if mode & need != need:
                packages.append(f"{entry.path} is not readable by other users ({stat.filemode(mode)})")
                break
    return interpreter, packages


def site_packages() -> list:
    """The directories of installed packages this interpreter imports from."""
    import site

    found = []
    # also the folders a .pth file put on sys.path (e.g. a venv that borrows another's packages)
    added = [p for p in sys.path if os.path.basename(p.rstrip(os.sep)) in ("site-packages", "dist-packages")]
    for path in list(site.getsitepackages()) + [sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]] \
            + added:
        real = os.path.realpath(path)
        if os.path.isdir(real) and real not in found:
            found.append(real)
    return found


def install_hint() -> str:
    return ("Install the grader's Python where every user can read it, e.g. as root "
            "`python3 -m venv /opt/autograder && /opt/autograder/bin/pip install -e <repository>` "
            "with a system Python (/usr/bin/python3) and the default umask 022, then run "
            "/opt/autograder/bin/python -m autograder. The grader does not run students' code as root.")


# ---------------------------------------------------------------- the reference


def _omitted(path) -> bool:
    """Whether the module ``path`` holds ``# RELEASE: omit`` in its first five lines."""
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return any(next(f, "").strip().startswith(OMIT_MARKER) for _ in range(5))
    except OSError:
        return False


def reference_paths(repo: Path = REPO_ROOT) -> list:
    """What the child must not read: ``solutions/``, ``autograder/mistakes/`` and every
    module whose first five lines hold ``# RELEASE: omit`` (outside those two)."""
    repo = Path(repo)
    found = [p for p in (repo / "solutions", repo / "autograder" / "mistakes") if p.is_dir()]
    skip = {".git", ".venv", "venv", "node_modules", "__pycache__", "build", "dist"}
    for directory, dirs, files in os.walk(repo):
        dirs[:] = [d for d in dirs if d not in skip and not d.startswith(".")
                   and Path(directory, d) not in found]
        found += [Path(directory, name) for name in files if name.endswith(".py") and _omitted(Path(directory, name))]
    return found


def protect_reference(repo: Path = REPO_ROOT) -> list:
    """Make the reference unreadable by others (directories 0700, files 0600 when they
    were readable by others); return what changed."""
    changed = []
    for path in reference_paths(repo):
        st = os.lstat(path)
        if stat.S_ISLNK(st.st_mode):
            continue
        if st.st_mode & 0o007:
            os.chmod(path, 0o700 if stat.S_ISDIR(st.st_mode) else 0o600)
            changed.append(path)
    return changed


# ---------------------------------------------------------------- staging


def _mirror(source: Path, target: Path, skip, place) -> None:
    """Directories and regular files of ``source`` under ``target`` (0755 folders, no
    symlinks, names in ``skip`` left out); ``place(path, dest)`` puts each file."""
    target.mkdir(mode=0o755)
    os.chmod(target, 0o755)
    for entry in os.scandir(source):
        if entry.name in skip or entry.is_symlink():
            continue
        if entry.is_dir(follow_symlinks=False):
            _mirror(Path(entry.path), target / entry.name, skip, place)
        elif entry.is_file(follow_symlinks=False):
            place(entry.path, target / entry.name)


def _copy_file(source, dest) -> None:
    shutil.copy2(source, dest, follow_symlinks=False)
    os.chmod(dest, 0o644)


def _copy_tree(source: Path, target: Path, skip=()) -> None:
    """Copy regular files and directories (no symlinks), root-owned, readable by all."""
    _mirror(source, target, skip, _copy_file)


def _copy_unless_omitted(source, dest) -> None:
    """Copy ``source`` unless it is an omitted module or the bytecode of one."""
    path = Path(source)
    module = path.parent.parent / (path.name.split(".")[0] + ".py") if path.suffix == ".pyc" else path
    if not (module.suffix == ".py" and _omitted(module)):
        _copy_file(source, dest)


def stage_framework(root: Path) -> None:
    """Copy what the child imports from the repository into ``root`` (created, root-owned,
    0755): ``course/`` with its bytecode (the children run with ``-B``), but the modules
    marked ``# RELEASE: omit``, and the runner and tasks of ``autograder/``."""
    root.mkdir(mode=0o755)
    os.chmod(root, 0o755)
    _mirror(REPO_ROOT / "course", root / "course", (), _copy_unless_omitted)
    package = root / "autograder"
    package.mkdir(mode=0o755)
    for name in AUTOGRADER_FILES:
        shutil.copy2(REPO_ROOT / "autograder" / name, package / name)
        os.chmod(package / name, 0o644)
    for name in AUTOGRADER_PACKAGES:
        _copy_tree(REPO_ROOT / "autograder" / name, package / name, skip={"__pycache__"})


def framework_files() -> list:
    """``(path, mtime_ns, size)`` of every file :func:`stage_framework` reads: a staged copy
    made before any of them changed is stale."""
    found = []
    tops = [REPO_ROOT / "course"] + [REPO_ROOT / "autograder" / name for name in AUTOGRADER_PACKAGES]
    for top in tops:
        for directory, dirs, files in os.walk(top):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            found += [os.path.join(directory, name) for name in sorted(files)]
    found += [str(REPO_ROOT / "autograder" / name) for name in AUTOGRADER_FILES]
    out = []
    for path in found:
        try:
            st = os.stat(path)
        except OSError:
            continue
        out.append((path, st.st_mtime_ns, st.st_size))
    return out


def stage_impl(impl: str, root: Path) -> str:
    """Copy the implementation ``impl`` (a name in the repository or a path) into ``root/impl``
    (a folder of its own for each one staged) and return the staged package directory for
    ``course.core.impl.load``."""
    source = Path(impl) if os.sep in impl else REPO_ROOT / impl
    (root / "impl").mkdir(mode=0o755, exist_ok=True)
    os.chmod(root / "impl", 0o755)
    folder = root / "impl" / str(len(list((root / "impl").iterdir())))
    folder.mkdir(mode=0o755)
    os.chmod(folder, 0o755)
    target = folder / (source.name or "submission")
    _copy_tree(source, target, skip={"__pycache__"})
    return str(target)


def stage_runtime(root: Path) -> dict:
    """A copy of this Python (interpreter, shared library, standard library) in ``root``,
    for when the installed one sits under a directory other users cannot search (e.g.
    pyenv in /root). Files are hard-linked when possible, else copied. Returns
    ``{"executable", "env"}``; the child adds the installed packages with
    ``site.addsitedir``."""
    base = Path(sys.base_prefix)
    version = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    executable = Path(os.path.realpath(sys.executable))
    (root / "bin").mkdir(parents=True, mode=0o755)
    (root / "lib").mkdir(mode=0o755)
    for path in (root, root / "bin", root / "lib"):
        os.chmod(path, 0o755)
    target = root / "bin" / version
    _link_or_copy(executable, target)
    for library in (base / "lib").glob("libpython*.so*"):
        if library.is_file():
            _link_or_copy(library.resolve(), root / "lib" / library.name)
    stdlib = Path(sysconfig.get_paths()["stdlib"])
    _link_tree(stdlib, root / "lib" / version)
    env = {"LD_LIBRARY_PATH": str(root / "lib")}
    return {"executable": str(target), "env": env}


def _link_or_copy(source, target) -> None:
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)
        os.chmod(target, os.stat(source).st_mode & 0o755 | 0o444)


def _link_tree(source: Path, target: Path, skip=LIBRARY_SKIP) -> None:
    """Hard links (else copies) of the files of ``source``, with their own modes."""
    _mirror(source, target, skip, _link_or_copy)


def stage_site_packages(sites: list, root: Path) -> list:
    """Copies of the package directories ``sites`` in ``root``, for when they sit under a
    directory other users cannot search (a venv in a 0700 home or temporary folder).
    Hard links where possible (about 0.5 s for 20,000 files), else copies; the files keep
    their own modes. Returns the staged directories, in order."""
    root.mkdir(parents=True, exist_ok=True, mode=0o755)
    os.chmod(root, 0o755)
    staged = []
    for number, site in enumerate(sites):
        target = root / f"site-packages-{number}"
        _link_tree(Path(site), target, skip=())  # bytecode too: the children run with -B
        staged.append(str(target))
    return staged


def temp_root() -> str:
    """A directory for the session's files that the child's uid can traverse."""
    base = tempfile.gettempdir()
    why = unreachable(base)
    if why:
        raise IsolationError(f"the temporary directory is not usable by the children's uid: {why}; "
                             "set TMPDIR to a directory every user can search (e.g. /tmp)")
    return base


# ---------------------------------------------------------------- uids


def _lock_dir() -> str:
    for parent in ("/run/lock", "/run", "/var/lock", tempfile.gettempdir()):
        if not os.path.isdir(parent):
            continue
        path = os.path.join(parent, "autograder-uids")
        try:
            os.mkdir(path, 0o700)
        except FileExistsError:
            pass
        except OSError:
            continue
        st = os.lstat(path)
        if stat.S_ISDIR(st.st_mode) and st.st_uid == 0 and not st.st_mode & 0o022:
            return path
    raise IsolationError("found no root-owned directory for the uid locks (tried /run/lock, /run, /var/lock, TMPDIR)")


def _id_free(number: int) -> bool:
    try:
        pwd.getpwuid(number)
        return False
    except KeyError:
        pass
    try:
        grp.getgrgid(number)
        return False
    except KeyError:
        return True


class Slot:
    """One worker slot: a uid and gid of its own, held with a lock file."""

    def __init__(self, number: int, lock_fd: int | None):
        self.uid = self.gid = number
        self.lock_fd = lock_fd
        self.memory_limit = None  # bytes while a check runs, watched by MemoryWatch
        self.memory_exceeded = False

    def release(self) -> None:
        if self.lock_fd is not None:
            os.close(self.lock_fd)
            self.lock_fd = None


def acquire_slots(count: int) -> list:
    """``count`` free uids, each locked until released (kills any leftover process)."""
    directory = _lock_dir()
    slots: list = []
    for number in range(FIRST_ID, FIRST_ID + ID_RANGE):
        if len(slots) == count:
            break
        if not _id_free(number):
            continue
        fd = os.open(os.path.join(directory, str(number)), os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o600)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        slot = Slot(number, fd)
        kill_uid(slot.uid, slot.gid)  # a crashed run's leftovers
        slots.append(slot)
    if len(slots) < count:
        for slot in slots:
            slot.release()
        raise IsolationError(f"no {count} free uids in {FIRST_ID}..{FIRST_ID + ID_RANGE - 1} "
                             "(too many grading runs at once?)")
    return slots


# ---------------------------------------------------------------- processes


def uid_pids(uid: int, *, zombies=False) -> list:
    """Pids of the processes whose real uid is ``uid`` (zombies only when asked)."""
    live, dead = processes(uid)
    return live + dead if zombies else live


def processes(uid: int) -> tuple:
    """``(live, zombies)``: the pids of ``uid``'s processes, from one pass over ``/proc``."""
    return processes_of((uid,))[uid]


def processes_of(uids) -> dict:
    """``{uid: (live, zombies)}`` for each of ``uids``, from one pass over ``/proc`` (it runs
    several times a check and 20 times a second while one runs, over every process of the
    machine: hence raw reads of the status file's first page, not ``open()``)."""
    found: dict = {uid: ([], []) for uid in uids}
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            fd = os.open(f"/proc/{name}/status", os.O_RDONLY | os.O_CLOEXEC)
        except OSError:
            continue
        try:
            status = os.read(fd, 4096)
        except OSError:
            continue
        finally:
            os.close(fd)
        try:  # the real uid, first of the Uid line
            real = int(status.split(b"\nUid:", 1)[1].split(None, 1)[0])
        except (IndexError, ValueError):
            continue
        if real not in found:
            continue
        zombie = status.split(b"\nState:", 1)[-1].lstrip().startswith(b"Z")
        found[real][1 if zombie else 0].append(int(name))
    return found


def _kill_as(uid: int, gid: int) -> None:
    """Fork a helper that takes the uid and calls ``kill(-1, SIGKILL)``: every process
    of that uid (but the helper) dies; no new one can be forked during that call."""
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the helper
        code = 1
        try:
            os.setgroups([])
            os.setresgid(gid, gid, gid)
            os.setresuid(uid, uid, uid)
            try:
                os.kill(-1, signal.SIGKILL)
            except ProcessLookupError:
                pass
            code = 0
        finally:
            os._exit(code)
    while True:
        try:
            os.waitpid(pid, 0)
            return
        except ChildProcessError:
            return
        except InterruptedError:
            continue


def kill_uid(uid: int, gid: int, deadline=2.0) -> bool:
    """Kill every process of ``uid``; True when none is left (zombies aside)."""
    end = time.monotonic() + deadline
    while True:
        live, dead = processes(uid)
        if not live:
            reap(uid, dead)
            return True
        _kill_as(uid, gid)
        live, dead = processes(uid)
        if not live:
            reap(uid, dead)
            return True
        if time.monotonic() > end:
            return False
        time.sleep(0.005)


#: pids of children a ``subprocess.Popen`` waits for: :func:`reap` leaves them alone
TRACKED: set = set()


def reap(uid: int, zombies=None) -> None:
    """Collect the zombies of ``uid`` (or the pids ``zombies``) that were reparented to this
    process (subreaper)."""
    me = os.getpid()
    for pid in uid_pids(uid, zombies=True) if zombies is None else zombies:
        if pid in TRACKED:
            continue
        try:
            with open(f"/proc/{pid}/stat") as f:
                ppid = int(f.read().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        if ppid == me:
            try:
                os.waitpid(pid, os.WNOHANG)
            except ChildProcessError:
                pass


_PR_SET_CHILD_SUBREAPER, _PR_GET_CHILD_SUBREAPER = 36, 37


def set_subreaper(on: bool) -> bool:
    """Make this process the reaper of its orphaned descendants; return the old setting."""
    old = is_subreaper()
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_CHILD_SUBREAPER, 1 if on else 0, 0, 0, 0)
    except Exception:  # noqa: BLE001 - not Linux, or no libc: orphans go to init
        pass
    return old


def is_subreaper() -> bool:
    """Whether this process reaps its orphaned descendants (False where that cannot be asked)."""
    try:
        import ctypes

        flag = ctypes.c_int(0)
        ctypes.CDLL(None, use_errno=True).prctl(_PR_GET_CHILD_SUBREAPER, ctypes.byref(flag), 0, 0, 0)
        return bool(flag.value)
    except Exception:  # noqa: BLE001 - not Linux, or no libc
        return False


#: a directory modified less than this long ago is not marked: file systems stamp times in ticks of
#: up to 2 s (FAT; ext3 and HFS+ in whole seconds), and a change within the tick keeps the mtime
MARK_AGE_NS = 2_000_000_000


def temp_marks(dirs=TEMP_DIRS) -> dict:
    """``{directory: mtime_ns}`` of the shared temporary directories last modified more than
    :data:`MARK_AGE_NS` ago: an entry made after this call changes its directory's mtime to a
    later time (a child can set it to now, never back), so ``sweep_temp(uid, unchanged=marks)``
    may skip a directory whose mtime is still the one marked."""
    now = time.time_ns()
    marks = {}
    for directory in dirs:
        try:
            mtime = os.stat(directory).st_mtime_ns
        except OSError:
            continue
        if mtime < now - MARK_AGE_NS:
            marks[directory] = mtime
    return marks


def sweep_temp(uid: int, dirs=TEMP_DIRS, unchanged=None) -> list:
    """Remove what ``uid`` left directly in the shared temporary directories (but those whose
    mtime is still the one in ``unchanged``, from :func:`temp_marks`)."""
    removed = []
    for directory in dirs:
        if unchanged and directory in unchanged:
            try:
                if os.stat(directory).st_mtime_ns == unchanged[directory]:
                    continue
            except OSError:
                continue
        try:
            entries = list(os.scandir(directory))
        except OSError:
            continue
        for entry in entries:
            try:
                st = entry.stat(follow_symlinks=False)
            except OSError:
                continue
            if st.st_uid != uid:
                continue
            try:
                if stat.S_ISDIR(st.st_mode):
                    shutil.rmtree(entry.path, ignore_errors=True)
                else:
                    os.unlink(entry.path)
                removed.append(entry.path)
            except OSError:
                pass
    return removed


def remove_tree(path) -> None:
    """``rm -rf`` that does not follow symlinks and survives odd permissions."""
    def retry(function, name, _info):
        try:
            parent = os.path.dirname(name)
            os.chmod(parent, 0o700)
            if os.path.isdir(name) and not os.path.islink(name):
                os.chmod(name, 0o700)
                shutil.rmtree(name, ignore_errors=True)
            else:
                os.unlink(name)
        except OSError:
            pass

    if os.path.lexists(path):
        shutil.rmtree(path, onerror=retry)


# ---------------------------------------------------------------- memory


def _memory(pid: int) -> int:
    """Proportional set size of ``pid`` in bytes (RSS when smaps_rollup is missing)."""
    try:
        with open(f"/proc/{pid}/smaps_rollup") as f:
            for line in f:
                if line.startswith("Pss:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError):
        pass
    return _resident(pid)


def _resident(pid: int) -> int:
    """Resident set size of ``pid`` in bytes (at least its PSS, and a cheap read: smaps_rollup
    walks the page tables)."""
    try:
        with open(f"/proc/{pid}/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


class MemoryWatch(threading.Thread):
    """Every ``interval`` s, sum the PSS of each slot's uid (one pass over ``/proc`` for all
    the slots whose check is running; the RSS first, which bounds it and costs far less to
    read); kill a uid's processes over its slot's limit."""

    def __init__(self, slots, interval=0.05):
        super().__init__(name="autograder-memory-watch", daemon=True)
        self.slots, self.interval = slots, interval
        self.stopped = threading.Event()

    def run(self):
        while not self.stopped.wait(self.interval):
            watched = [slot for slot in self.slots if slot.memory_limit is not None]
            if not watched:
                continue
            try:
                pids = processes_of({slot.uid for slot in watched})
            except OSError:
                continue
            for slot in watched:
                limit = slot.memory_limit
                live = pids[slot.uid][0]
                if limit is None or sum(_resident(pid) for pid in live) <= limit:
                    continue  # the RSS bounds the PSS: no need to walk the page tables
                if sum(_memory(pid) for pid in live) > limit and slot.memory_limit is not None:
                    slot.memory_exceeded = True
                    kill_uid(slot.uid, slot.gid, deadline=0.5)

    def stop(self):
        self.stopped.set()
        self.join(timeout=2)
