"""systemd/: the unit, its real-time drop-in, the sysusers file, the udev rule and the .link file.

The unit is installed as a user would install it (a copy whose ``ExecStart=`` is the installed
``navgw`` console script, here the venv's) and checked with systemd's own tools:
``systemd-analyze verify`` with and without the drop-in, ``systemd-analyze security`` for what
the drop-in lifts, ``systemd-sysusers`` on a scratch root, and udev's parsers for the rules and
the .link file. The tools come with Debian's ``systemd`` and ``udev`` packages (.ci/run installs
them); a test skips only when its tool is absent, or when the host forbids the private
namespaces that keep udevadm off the host's /run.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from gateway.config.gateway_config import load_config

ROOT = Path(__file__).resolve().parents[1]
SYSTEMD = ROOT / "systemd"
UNIT = SYSTEMD / "navgw.service"
DROP_IN = SYSTEMD / "navgw-realtime.conf"
SYSUSERS = SYSTEMD / "navgw.sysusers.conf"
RULES = SYSTEMD / "60-navgw.rules"
LINK = SYSTEMD / "10-navgw-can.link"
README = SYSTEMD / "README.md"

SHIPPED_EXEC_START = "/usr/bin/navgw run --config /etc/navgw/navgw.toml"

SYSTEMD_ANALYZE = shutil.which("systemd-analyze")
SYSTEMD_SYSUSERS = shutil.which("systemd-sysusers")
UDEVADM = shutil.which("udevadm")

needs_analyze = pytest.mark.skipif(
    SYSTEMD_ANALYZE is None,
    reason="systemd-analyze is not installed (Debian package systemd; .ci/run installs it)",
)


# --- reading the files ---------------------------------------------------------------------


def parse_ini(path: Path) -> dict[str, list[tuple[str, str]]]:
    """The sections of a systemd unit/.link file, each as its (key, value) lines in order
    (keys such as DeviceAllow= repeat, so no dict per section)."""
    sections: dict[str, list[tuple[str, str]]] = {}
    current: list[tuple[str, str]] | None = None
    for number, raw in enumerate(path.read_text().splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith(("#", ";")):
            continue
        assert not line.endswith("\\"), f"{path.name}:{number}: continuation lines not expected"
        if line.startswith("["):
            assert line.endswith("]"), f"{path.name}:{number}: {raw!r}"
            current = sections.setdefault(line[1:-1], [])
            continue
        assert current is not None, f"{path.name}:{number}: a key before any section"
        key, sep, value = line.partition("=")
        assert sep, f"{path.name}:{number}: not KEY=VALUE: {raw!r}"
        current.append((key.strip(), value.strip()))
    return sections


def values(sections: dict[str, list[tuple[str, str]]], section: str, key: str) -> list[str]:
    return [v for k, v in sections.get(section, []) if k == key]


def value(sections: dict[str, list[tuple[str, str]]], section: str, key: str) -> str:
    """The one value of a key that must be set exactly once."""
    found = values(sections, section, key)
    assert len(found) == 1, f"[{section}] {key}= set {len(found)} times: {found}"
    return found[0]


def navgw_entry_point() -> Path:
    """The installed ``navgw`` console script: the venv's, else the one on PATH."""
    candidate = Path(sys.prefix) / "bin" / "navgw"
    if candidate.is_file():
        return candidate
    found = shutil.which("navgw")
    assert found, "the navgw console script is not installed (pip install -e .)"
    return Path(found)


def install_unit(directory: Path, realtime: bool, drop_in_extra: str = "") -> Path:
    """navgw.service (and optionally the real-time drop-in) installed in ``directory`` as the
    README says, with ExecStart= at the installed console script instead of /usr/bin/navgw."""
    text = UNIT.read_text()
    exec_start = f"{navgw_entry_point()} run --config /etc/navgw/navgw.toml"
    installed, count = re.subn(
        rf"^ExecStart={re.escape(SHIPPED_EXEC_START)}$",
        lambda _: f"ExecStart={exec_start}",
        text,
        flags=re.MULTILINE,
    )
    assert count == 1, "navgw.service no longer has the ExecStart= line the README describes"
    directory.mkdir(parents=True, exist_ok=True)
    unit = directory / "navgw.service"
    unit.write_text(installed)
    if realtime:
        drop_ins = directory / "navgw.service.d"
        drop_ins.mkdir()
        (drop_ins / "realtime.conf").write_text(DROP_IN.read_text() + drop_in_extra)
    return unit


def run(*args: str | Path, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(a) for a in args], capture_output=True, text=True, timeout=timeout, check=False
    )


def verify(unit: Path) -> tuple[int, list[str]]:
    """``systemd-analyze verify``: exit status and its output lines about navgw's files."""
    assert SYSTEMD_ANALYZE is not None
    result = run(SYSTEMD_ANALYZE, "verify", unit)
    lines = (result.stdout + result.stderr).splitlines()
    ours = [line for line in lines if "navgw" in line or str(unit.parent) in line]
    return result.returncode, ours


# --- the unit ------------------------------------------------------------------------------


def test_the_unit_restarts_for_ever_except_on_a_bad_config() -> None:
    """Issue 12: no start limit (a burst of crashes must not leave the gateway failed for good)
    and no restart after exit 2 (a bad config, which a restart cannot fix)."""
    unit = parse_ini(UNIT)
    assert value(unit, "Unit", "StartLimitIntervalSec") == "0"
    assert "2" in " ".join(values(unit, "Service", "RestartPreventExitStatus")).split()
    assert value(unit, "Service", "Restart") == "on-failure"
    assert value(unit, "Service", "ExecStart") == SHIPPED_EXEC_START


def test_the_unit_is_notify_with_a_watchdog_and_keeps_its_hardening() -> None:
    unit = parse_ini(UNIT)
    service = dict(unit["Service"])  # the last value of repeated keys; these are set once
    assert service["Type"] == "notify"
    assert service["NotifyAccess"] == "main"
    assert service["WatchdogSec"] == "5s"
    assert (service["User"], service["Group"]) == ("navgw", "navgw")
    assert service["SupplementaryGroups"] == "dialout"
    hardening = {
        "CapabilityBoundingSet": "",
        "AmbientCapabilities": "",
        "NoNewPrivileges": "yes",
        "ProtectSystem": "strict",
        "ProtectHome": "yes",
        "PrivateTmp": "yes",
        "DevicePolicy": "closed",
        "RestrictRealtime": "yes",
        "RestrictNamespaces": "yes",
        "MemoryDenyWriteExecute": "yes",
        "SystemCallFilter": "@system-service",
    }
    assert {key: service.get(key) for key in hardening} == hardening
    # the serial receiver, also behind the udev symlink /dev/navgw-gnss (a ttyUSB/ttyACM node)
    assert set(values(unit, "Service", "DeviceAllow")) == {
        "char-ttyUSB rw",
        "char-ttyS rw",
        "char-ttyACM rw",
    }
    assert "AF_CAN" in service["RestrictAddressFamilies"].split()


@needs_analyze
@pytest.mark.parametrize("realtime", [False, True], ids=["unit", "unit+realtime-drop-in"])
def test_systemd_analyze_verify_passes_on_the_installed_unit(
    tmp_path: Path, realtime: bool
) -> None:
    unit = install_unit(tmp_path / "system", realtime)
    status, ours = verify(unit)
    assert (status, ours) == (0, [])


@needs_analyze
def test_verify_reads_the_drop_in_beside_the_unit(tmp_path: Path) -> None:
    """The control for the test above: a mistake in the drop-in is reported, so the drop-in
    really is verified there (verify still exits 0 on a warning: hence the output check)."""
    unit = install_unit(tmp_path / "system", realtime=True, drop_in_extra="NoSuchSetting=1\n")
    _, ours = verify(unit)
    assert any("realtime.conf" in line and "NoSuchSetting" in line for line in ours), ours


@needs_analyze
def test_verify_as_shipped_needs_navgw_in_usr_bin(tmp_path: Path) -> None:
    """Why the test installs the unit first: as shipped it names /usr/bin/navgw."""
    if Path("/usr/bin/navgw").exists():
        pytest.skip("/usr/bin/navgw exists here")
    shipped = tmp_path / "navgw.service"
    shutil.copy(UNIT, shipped)
    status, ours = verify(shipped)
    assert status != 0
    assert any("/usr/bin/navgw" in line for line in ours), ours


@needs_analyze
def test_the_realtime_drop_in_lifts_restrict_realtime_and_nothing_else(tmp_path: Path) -> None:
    drop_in = parse_ini(DROP_IN)
    assert set(drop_in) == {"Service"}
    assert dict(drop_in["Service"]) == {
        "CPUSchedulingPolicy": "fifo",
        "CPUSchedulingPriority": "50",
        "RestrictRealtime": "no",
        "LimitRTPRIO": "0",
    }

    def exposures(unit: Path) -> dict[str, bool | None]:
        assert SYSTEMD_ANALYZE is not None
        result = run(SYSTEMD_ANALYZE, "security", "--offline=true", "--json=short", unit)
        if result.returncode != 0 and "json" in result.stderr.lower():
            pytest.skip(f"systemd-analyze security has no --json here: {result.stderr.strip()}")
        assert result.returncode == 0, result.stderr
        return {check["name"]: check["set"] for check in json.loads(result.stdout)}

    plain = exposures(install_unit(tmp_path / "plain", realtime=False))
    realtime = exposures(install_unit(tmp_path / "realtime", realtime=True))
    assert plain["RestrictRealtime="] is True
    changed = {name for name in plain if plain[name] != realtime.get(name)}
    assert changed == {"RestrictRealtime="}


@pytest.mark.skipif(
    SYSTEMD_SYSUSERS is None,
    reason="systemd-sysusers is not installed (Debian package systemd; .ci/run installs it)",
)
def test_sysusers_creates_the_unit_user_in_dialout(tmp_path: Path) -> None:
    etc = tmp_path / "etc"
    etc.mkdir()
    (etc / "passwd").write_text("root:x:0:0:root:/root:/bin/bash\n")
    (etc / "group").write_text("root:x:0:\ndialout:x:20:\n")
    assert SYSTEMD_SYSUSERS is not None
    result = run(SYSTEMD_SYSUSERS, f"--root={tmp_path}", SYSUSERS)
    assert result.returncode == 0, result.stderr
    passwd = {
        line.split(":")[0]: line.split(":") for line in (etc / "passwd").read_text().splitlines()
    }
    groups = {
        line.split(":")[0]: line.split(":") for line in (etc / "group").read_text().splitlines()
    }
    unit = parse_ini(UNIT)
    user = value(unit, "Service", "User")
    assert passwd[user][5] == "/var/lib/navgw"  # the unit's StateDirectory=
    assert passwd[user][3] == groups[value(unit, "Service", "Group")][2]
    assert user in groups[value(unit, "Service", "SupplementaryGroups")][3].split(",")


# --- udev: the GNSS receiver's symlink and the CAN interface's name ------------------------

UDEV_MATCH_KEYS = {
    "ACTION", "DEVPATH", "KERNEL", "KERNELS", "NAME", "SYMLINK", "SUBSYSTEM", "SUBSYSTEMS",
    "DRIVER", "DRIVERS", "ATTR", "ATTRS", "SYSCTL", "TAG", "TAGS", "ENV", "CONST", "TEST",
    "PROGRAM", "RESULT",
}  # fmt: skip
UDEV_ASSIGN_KEYS = {
    "NAME", "SYMLINK", "OWNER", "GROUP", "MODE", "SECLABEL", "ATTR", "SYSCTL", "ENV", "TAG",
    "RUN", "LABEL", "GOTO", "IMPORT", "OPTIONS",
}  # fmt: skip
UDEV_TOKEN = re.compile(
    r'(?P<key>[A-Z_]+)(?:\{(?P<attr>[^}]*)\})?\s*(?P<op>==|!=|\+=|-=|:=|=)\s*"(?P<value>[^"]*)"'
)
#: A rule commented out as an example: "#KEY==..." (prose comments have a space after "#").
COMMENTED_RULE = re.compile(r"^#(?=[A-Z]+(?:\{[^}]*\})?(?:==|!=|\+=|:=|=)\")")


def udev_rules(text: str) -> list[tuple[bool, list[tuple[str, str, str]]]]:
    """(active?, [(key, operator, value), ...]) of each rule, also of the commented examples.
    Stricter than udev 252: tokens must be separated by commas (newer udevadm verify asks)."""
    rules = []
    for number, raw in enumerate(text.splitlines(), 1):
        active = not raw.startswith("#")
        line = COMMENTED_RULE.sub("", raw).strip()
        if not line or line.startswith("#"):
            continue
        tokens, position = [], 0
        while True:
            match = UDEV_TOKEN.match(line, position)
            assert match, f'line {number}: no KEY=="value" at column {position}: {raw!r}'
            tokens.append((match["key"], match["op"], match["value"]))
            position = match.end()
            rest = line[position:]
            if not rest.strip():
                break
            separator = re.match(r"\s*,\s*", rest)
            assert separator, f"line {number}: tokens must be separated by commas: {raw!r}"
            position += separator.end()
        for key, op, _ in tokens:
            if op in ("==", "!="):
                assert key in UDEV_MATCH_KEYS, f"line {number}: {key} cannot be matched"
            else:
                assert key in UDEV_ASSIGN_KEYS, f"line {number}: {key} cannot be assigned"
        rules.append((active, tokens))
    return rules


def test_the_udev_rule_gives_the_receiver_one_stable_name_and_nothing_else() -> None:
    rules = udev_rules(RULES.read_text())
    assert len(rules) >= 4  # the active one and the commented examples
    for _, tokens in rules:
        matches = [t for t in tokens if t[1] in ("==", "!=")]
        assignments = [t for t in tokens if t not in matches]
        assert ("SUBSYSTEM", "==", "tty") in matches
        assert len(matches) >= 2, tokens  # something that picks the receiver
        # the name only: the node keeps the distribution's group dialout and mode
        assert assignments == [("SYMLINK", "+=", "navgw-gnss")]
    assert [active for active, _ in rules].count(True) == 1  # one receiver gets the name


def test_the_link_file_names_the_can_interface() -> None:
    link = parse_ini(LINK)
    assert set(link) == {"Match", "Link"}
    assert link["Match"], "an empty [Match] would match (or, in newer systemd, skip) everything"
    match_keys = {
        "MACAddress", "PermanentMACAddress", "Path", "Driver", "Type", "Kind", "Property",
        "OriginalName", "Host", "Virtualization", "KernelCommandLine", "KernelVersion",
        "Architecture", "Firmware", "Credential",
    }  # fmt: skip
    assert {key for key, _ in link["Match"]} <= match_keys
    assert value(link, "Match", "Type") == "can"
    assert dict(link["Link"]).keys() == {"Name"}  # no NamePolicy=: it would take precedence
    name = value(link, "Link", "Name")
    assert name == "isobus0"
    assert re.fullmatch(r"[A-Za-z0-9_-]{1,15}", name)  # IFNAMSIZ - 1, no '/', ':' or space
    # the commented Path= examples are ID_PATH values
    examples = re.findall(r"^#Path=(\S+)$", LINK.read_text(), flags=re.MULTILINE)
    assert examples and all(re.fullmatch(r"(platform|pci)-\S+", e) for e in examples)


def udev_parse_in_private_namespaces(
    tmp_path: Path, rules: dict[str, str], links: dict[str, str]
) -> subprocess.CompletedProcess[str]:
    """Runs ``udevadm test`` with ``rules`` in /run/udev/rules.d and ``links`` in
    /run/systemd/network, where udev reads them, inside private mount and network namespaces
    over a scratch /run: the host's /run, devices and interfaces stay untouched. udevadm
    parses every rules and .link file when it starts; the event (for lo) is simulated."""
    assert UDEVADM is not None
    staged = tmp_path / "staged"
    for directory, files in (("rules.d", rules), ("network", links)):
        (staged / directory).mkdir(parents=True)
        for name, text in files.items():
            (staged / directory / name).write_text(text)
    script = (
        "set -e; mount -t tmpfs navgw-test /run; "
        'mkdir -p /run/udev /run/systemd; cp -r "$1/rules.d" /run/udev/rules.d; '
        'cp -r "$1/network" /run/systemd/network; exec "$2" test /sys/class/net/lo'
    )
    return run("unshare", "--mount", "--net", "sh", "-c", script, "sh", staged, UDEVADM)


@pytest.mark.skipif(
    UDEVADM is None or shutil.which("unshare") is None,
    reason="udevadm (Debian package udev; .ci/run installs it) or unshare is not installed",
)
def test_udev_itself_parses_the_rules_and_the_link_file(tmp_path: Path) -> None:
    udevadm = UDEVADM
    assert udevadm is not None
    rules_text = RULES.read_text()
    # the commented examples too, as a user would uncomment them
    examples = "".join(
        COMMENTED_RULE.sub("", line) + "\n"
        for line in rules_text.splitlines()
        if COMMENTED_RULE.match(line)
    )
    link_text = LINK.read_text()
    broken_rules = 'SUBSYSTEM="tty", NO_SUCH_KEY=="1", SYMLINK+="x"\n'
    broken_link = "[Match]\nType=can\nNoSuchMatch=1\n[Link]\nNoSuchSetting=1\n"
    result = udev_parse_in_private_namespaces(
        tmp_path,
        rules={
            "60-navgw.rules": rules_text,
            "61-navgw-examples.rules": examples,
            "69-broken.rules": broken_rules,
        },
        links={"10-navgw-can.link": link_text, "11-broken.link": broken_link},
    )
    output = result.stdout + result.stderr
    if result.returncode != 0 and "unshare" in output and "Operation not permitted" in output:
        pytest.skip(f"no private namespaces here (needs root / CAP_SYS_ADMIN): {output.strip()}")
    assert result.returncode == 0, output
    lines = output.splitlines()
    # the control: udev read the files and reports mistakes as "FILE:LINE ..."
    assert any("69-broken.rules:" in line for line in lines), output
    assert any("11-broken.link:" in line for line in lines), output
    for name in ("60-navgw.rules", "61-navgw-examples.rules", "10-navgw-can.link"):
        assert any(name in line for line in lines), f"udevadm did not read {name}:\n{output}"
        assert not [line for line in lines if f"{name}:" in line], output

    if run(udevadm, "verify", "--help").returncode == 0:  # systemd >= 254
        for name in ("60-navgw.rules", "61-navgw-examples.rules"):
            strict = run(
                udevadm, "verify", "--resolve-names=never", tmp_path / "staged/rules.d" / name
            )
            assert strict.returncode == 0, strict.stdout + strict.stderr


# --- the names in the README's config --------------------------------------------------------


def readme_config_example() -> str:
    """The README's navgw.toml example: the indented block that starts with '    [imu]'."""
    lines = README.read_text().splitlines()
    start = lines.index("    [imu]")
    block = []
    for line in lines[start:]:
        if not line.startswith("    "):
            break
        block.append(line[4:])
    return "\n".join(block) + "\n"


def test_the_readme_config_uses_the_names_the_rule_and_link_file_give(tmp_path: Path) -> None:
    config_file = tmp_path / "navgw.toml"
    config_file.write_text(readme_config_example())
    config = load_config(config_file)  # keys the gateway knows, values it accepts
    link_name = value(parse_ini(LINK), "Link", "Name")
    assert config.imu.channel == link_name
    assert config.isobus.channel in (None, link_name)  # unset: the [imu] bus
    assert config.gnss.port == "/dev/navgw-gnss"
    readme = README.read_text()
    assert f"Name={link_name}" in readme  # the systemd-networkd example brings it up
    for path in SYSTEMD.iterdir():  # every file here has its install step in the README
        assert path.name == "README.md" or path.name in readme, path.name
