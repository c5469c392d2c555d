"""Commands the documentation gives, run as written: a newcomer who follows the organiser's
guide word for word meets no traceback and no step that fails."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def blocks(doc: Path, section: str, lang: str) -> list[str]:
    """The ```lang code blocks of the section whose heading starts with ``section``."""
    text = doc.read_text()
    start = text.index(f"\n## {section}")
    end = text.find("\n## ", start + 4)
    part = text[start:end if end > 0 else None]
    return re.findall(rf"```{lang}\n(.*?)```", part, re.S)


def test_organiser_section_1_as_written(tmp_path: Path) -> None:
    doc = ROOT / "docs" / "organiser.md"
    sh = blocks(doc, "1.", "sh")
    assert len(sh) == 2, sh
    (tmp_path / "team_templates").symlink_to(ROOT / "team_templates")  # the guide runs in the repository
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")
    for block in sh:
        p = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", block], cwd=tmp_path, env=env, capture_output=True,
                           text=True, timeout=120)
        assert p.returncode == 0 and "Traceback" not in p.stderr, f"{block}\n{p.stdout}\n{p.stderr}"
    assert (tmp_path / "arenas" / "final.toml").is_file()
    assert "playable" in p.stdout or "cost" in p.stdout  # the second block checked and planned
    (py,) = blocks(doc, "1.", "python")
    p = subprocess.run([sys.executable, "-c", py], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, f"{py}\n{p.stdout}\n{p.stderr[-3000:]}"
    assert (tmp_path / "final-dryrun.jsonl").is_file()


def test_tutorial_sections_2_to_4_as_written(tmp_path: Path) -> None:
    """The tutorial's match by hand: its commands run as written (with its /tmp/match moved into
    the test's folder), and what it shows them printing is what they print."""
    import time

    doc = ROOT / "docs" / "tutorial.md"
    match = str(tmp_path / "match")
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")
    start = blocks(doc, "2.", "sh")
    procs = []
    try:
        lines = [ln for ln in start[0].splitlines() if ln.strip()]
        assert len(lines) == 2 and lines[0].startswith("robo-comp core") and lines[1].startswith("robo-comp robots")
        # ("exec": terminate() then stops the command, not only its shell; "--port 0": this machine is
        # shared, the tutorial's default port 5555 may be another match's)
        core = subprocess.Popen("exec " + lines[0].replace("/tmp/match", match) + " --port 0", shell=True, env=env,
                                cwd=tmp_path,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        procs.append(core)
        assert "serving 'Demo room'" in (core.stdout.readline() if core.stdout else "")
        robots = subprocess.Popen("exec " + lines[1].replace("/tmp/match", match), shell=True, env=env, cwd=tmp_path,
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        procs.append(robots)
        assert "registered" in (robots.stdout.readline() if robots.stdout else "")

        def shown(block: str) -> list[tuple[str, list[str]]]:
            """``$ command`` lines with the output the tutorial shows under each."""
            out: list[tuple[str, list[str]]] = []
            for ln in block.splitlines():
                if ln.startswith("$ "):
                    out.append((ln[2:], []))
                elif out:
                    out[-1][1].append(ln.rstrip())
            return out

        for cmd, want in shown(start[1]) + shown(blocks(doc, "3.", "sh")[0]):
            cmd = cmd.replace("/tmp/match", match)
            if " events " in cmd:
                events = subprocess.Popen("exec " + cmd.replace(" events ", " --json events "), shell=True, env=env, cwd=tmp_path, text=True,
                                          stdout=subprocess.PIPE, stderr=subprocess.PIPE)
                procs.append(events)
                time.sleep(1.5)
                continue
            p = subprocess.run(cmd, shell=True, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=60)
            assert p.returncode == 0, f"{cmd}\n{p.stdout}{p.stderr}"
            assert [ln.rstrip() for ln in p.stdout.splitlines()] == want, f"{cmd}\nshown:\n" + "\n".join(want) + \
                f"\nprinted:\n{p.stdout}"
        events = procs[-1]
        events.wait(60)
        seen = [__import__("json").loads(ln) for ln in events.stdout.read().splitlines() if ln.strip()]  # type: ignore[union-attr]
        pictures = [e["data"] for e in seen if e["topic"] == "picture"]
        assert [p["id"] for p in pictures] == [1, 2, 3, 4]  # each once
        assert pictures[0]["heading"] == 270.0 and pictures[0]["victims"] == ["v1"], pictures[0]
        (py,) = blocks(doc, "4.", "python")
        p = subprocess.run([sys.executable, "-c", py.replace("/tmp/match", match)], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=60)
        assert p.returncode == 0, p.stderr
        assert "'state': 'confirmed', 'message': 'victim v1 (adult) found'" in p.stdout, p.stdout
        assert "'team': 'red', 'score': 15.0, 'victims': 1" in p.stdout, p.stdout
    finally:
        for pr in reversed(procs):
            pr.terminate()
            pr.wait(10)


def _pty_console(cmd: str, cwd: Path, env: dict[str, str], want: list[str], timeout: float = 90.0) -> tuple[str, int]:
    """Run a full-screen console in a pseudo-terminal of 100×30 as a person's terminal would; once
    every string of ``want`` is on the screen (escape sequences stripped), press ctrl+q. Returns
    what it drew and its exit status."""
    import fcntl
    import pty
    import select
    import struct
    import termios
    import time

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    proc = subprocess.Popen("exec " + cmd, shell=True, cwd=cwd, env=dict(env, TERM="xterm-256color"),
                            stdin=slave, stdout=slave, stderr=slave, start_new_session=True)
    os.close(slave)
    raw = b""
    ansi = re.compile(r"\x1b(\[[0-?]*[ -/]*[@-~]|\][^\x07\x1b]*(\x07|\x1b\\)|[PX^_][^\x1b]*\x1b\\|[@-Z\\-_])")
    t_end = time.monotonic() + timeout
    quit_sent = False
    try:
        while time.monotonic() < t_end:
            ready, _, _ = select.select([master], [], [], 0.2)
            if ready:
                try:
                    raw += os.read(master, 65536)
                except OSError:  # the console exited and closed the terminal
                    break
            text = ansi.sub("", raw.decode("utf-8", "replace"))
            if not quit_sent and all(w in text for w in want):
                os.write(master, b"\x11")  # ctrl+q
                quit_sent = True
            if proc.poll() is not None:
                break
        rc = proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    return ansi.sub("", raw.decode("utf-8", "replace")), rc


def test_readme_session_by_hand_as_written(tmp_path: Path) -> None:
    """The README's "A session by hand": a core, the organiser's host, a team's ctl commands and
    the team console, run as written (from the repository, its /tmp/match moved into the test's
    folder, the core on a free port: this machine is shared), each printing what a newcomer expects."""
    text = (ROOT / "README.md").read_text()
    (block,) = re.findall(r"A session by hand:\n\n```sh\n(.*?)```", text, re.S)
    lines = [ln for ln in block.splitlines() if ln.strip() and not ln.startswith("#")]
    # run at once, ctl finds no robot yet (the host takes seconds to start): the README says to wait
    said_wait = block.split(lines[1], 1)[1].split(lines[2], 1)[0]
    assert "registered" in said_wait, "the README should say to wait for the host's 'registered' line"
    match = str(tmp_path / "match")
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")
    venv_bin = ".venv/bin/" if (ROOT / ".venv" / "bin" / "robo-comp").exists() else f"{Path(sys.executable).parent}/"

    def as_run(line: str) -> str:
        cmd = line.split("   # ")[0].split("      # ")[0].strip()
        return cmd.replace("/tmp/match", match).replace(".venv/bin/", venv_bin)

    assert [ln.split()[1] for ln in lines] == ["core", "robots", "ctl", "ctl", "ctl", "ctl", "ctl", "team"], lines
    assert lines[0].endswith("&") and lines[1].split("   #")[0].rstrip().endswith("&")
    procs: list[subprocess.Popen[str]] = []
    try:
        core = subprocess.Popen("exec " + as_run(lines[0]).rstrip("& ") + " --port 0", shell=True, cwd=ROOT, env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        procs.append(core)
        first = core.stdout.readline() if core.stdout else ""
        assert "core: serving 'Default arena' for teams red, blue" in first, first
        robots = subprocess.Popen("exec " + as_run(lines[1]).rstrip("& "), shell=True, cwd=ROOT, env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        procs.append(robots)
        said = robots.stdout.readline() if robots.stdout else ""
        assert "robots: team red: 3 robot(s) registered with the core" in said and "tags 101, 102, 103" in said, said
        expect = [  # what each ctl command prints, as a pattern
            r"tag team +status.*\n +101 red +connected .*\n +102 red +connected .*\n +103 red +connected ",
            r"^task (\d+) given to robot 101: goTo \[3, 4\] \[now\]$",
            r"^robot 101: ok square\.py: square 1\.0 loaded$",
            r"^task (\d+) given to robot 101: square \[2\] \[now\]",
            # (the square may have ended already on a loaded machine: then it cancels none)
            r"^robot 101 halted at \(\d+\.\d\d, \d+\.\d\d\) in [\d.]+ ms; cancelled tasks: (\[\d+(, \d+)*\]|none)$",
        ]
        for line, pattern in zip(lines[2:7], expect):
            p = subprocess.run(as_run(line), shell=True, cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
            assert p.returncode == 0 and "Traceback" not in p.stderr, f"{line}\n{p.stdout}{p.stderr}"
            assert re.search(pattern, p.stdout, re.M), f"{line}\nprinted:\n{p.stdout}"
        # the console of team red, online, robot 101 selected, its monitor listing the uploaded task
        want = ["robo_comp · team red", "● online", "Monitor · robot 101", "square(side: "]
        shown, rc = _pty_console(as_run(lines[7]), ROOT, env, want)
        assert all(w in shown for w in want), shown[-3000:]
        assert rc == 0 and "Traceback" not in shown, shown[-3000:]
    finally:
        for pr in reversed(procs):
            pr.terminate()
            pr.wait(10)
