"""Which Fast DDS profile a process takes (``bracing_ros.fastdds``): a profile from the environment is
used only if it cannot open a socket off the loopback interface; otherwise the project's loopback
profile replaces it, and the process says why. (That the sockets are then on 127.0.0.1 is
test_loopback.py's, with ``ss``'s view of a real run.)"""

from __future__ import annotations

from pathlib import Path

import pytest

from bracing_ros import fastdds
from bracing_ros.fastdds import (
    FASTDDS_NETWORK_PROFILE,
    FASTDDS_PROFILE,
    PROFILE_ENV,
    RANGE_ENV,
    SKIP_ENV,
    loopback_problem,
    use_fastdds_profile,
)

HEAD = '<?xml version="1.0"?>\n<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">'
LOOPBACK_UDP = """<transport_descriptors><transport_descriptor><transport_id>udp</transport_id><type>UDPv4</type>
  <interfaceWhiteList><address>{address}</address></interfaceWhiteList></transport_descriptor>
  <transport_descriptor><transport_id>shm</transport_id><type>SHM</type></transport_descriptor></transport_descriptors>"""
PARTICIPANT = """<participant profile_name="p" is_default_profile="true"><rtps>
  <userTransports><transport_id>shm</transport_id><transport_id>udp</transport_id></userTransports>
  <useBuiltinTransports>{builtin}</useBuiltinTransports>
  <builtin>{locators}</builtin></rtps></participant>"""
LOCATOR = "<locator><udpv4><address>{address}</address></udpv4></locator>"
UNICAST = "<metatrafficUnicastLocatorList>" + LOCATOR + "</metatrafficUnicastLocatorList>"
MULTICAST_TAGS = ("<metatrafficMulticastLocatorList>", "</metatrafficMulticastLocatorList>")
MULTICAST = LOCATOR.format(address="239.255.0.1").join(MULTICAST_TAGS)


def profile(tmp_path: Path, allow: str = "127.0.0.1", builtin: str = "false", locators: str | None = None) -> Path:
    path = tmp_path / "mine.xml"
    body = PARTICIPANT.format(
        builtin=builtin, locators=UNICAST.format(address="127.0.0.1") if locators is None else locators
    )
    path.write_text(HEAD + LOOPBACK_UDP.format(address=allow) + body + "</profiles>")
    return path


def test_the_projects_profiles_are_judged_as_they_are() -> None:
    assert loopback_problem(FASTDDS_PROFILE) is None
    assert "built-in transports" in str(loopback_problem(FASTDDS_NETWORK_PROFILE))


@pytest.mark.parametrize(
    ("kwargs", "reason"),
    [
        ({}, None),
        ({"allow": "lo"}, None),
        ({"allow": "127.0.0.2"}, None),
        ({"allow": "0.0.0.0"}, "not kept to loopback addresses (['0.0.0.0'])"),
        ({"allow": "192.168.1.5"}, "not kept to loopback addresses"),
        ({"builtin": "true"}, "built-in transports"),
        ({"locators": ""}, "names no metatrafficUnicastLocatorList"),
        ({"locators": UNICAST.format(address="127.0.0.1") + MULTICAST}, "listens on multicast"),
        ({"locators": UNICAST.format(address="10.0.0.7")}, "addresses off loopback (['10.0.0.7'])"),
    ],
)
def test_a_users_profile_is_judged_by_what_it_could_open(
    tmp_path: Path, kwargs: dict[str, str], reason: str | None
) -> None:
    problem = loopback_problem(profile(tmp_path, **kwargs))
    assert (problem is None) if reason is None else (reason in str(problem)), problem


def test_unreadable_and_incomplete_profiles_are_not_trusted(tmp_path: Path) -> None:
    assert "cannot be read" in str(loopback_problem(tmp_path / "missing.xml"))
    (tmp_path / "bad.xml").write_text("<profiles><participant")
    assert "cannot be read" in str(loopback_problem(tmp_path / "bad.xml"))
    (tmp_path / "writer.xml").write_text(HEAD + '<data_writer profile_name="w" is_default_profile="true"/></profiles>')
    assert "no default participant profile" in str(loopback_problem(tmp_path / "writer.xml"))
    (tmp_path / "ghost.xml").write_text(HEAD + PARTICIPANT.format(builtin="false", locators="") + "</profiles>")
    assert "'shm' is not described" in str(loopback_problem(tmp_path / "ghost.xml"))


@pytest.fixture
def environment(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> pytest.MonkeyPatch:
    for key in (PROFILE_ENV, SKIP_ENV, fastdds.NETWORK_ENV):
        # set first, so that monkeypatch restores each as it was, absent included (use_fastdds_profile writes
        # os.environ itself: a profile left behind would be every later test's, --network runs' included)
        monkeypatch.setenv(key, "")
        monkeypatch.delenv(key)
    monkeypatch.setenv(RANGE_ENV, "LOCALHOST")  # env.sh's
    monkeypatch.chdir(tmp_path)
    return monkeypatch


def test_nothing_exported_takes_the_loopback_profile(environment: pytest.MonkeyPatch) -> None:
    assert use_fastdds_profile() is None
    assert fastdds.os.environ[PROFILE_ENV] == str(FASTDDS_PROFILE)
    assert fastdds.os.environ[RANGE_ENV] == "SYSTEM_DEFAULT"  # rmw's LOCALHOST range would add a UDP transport


def test_the_projects_own_profile_exported_keeps_to_loopback(environment: pytest.MonkeyPatch) -> None:
    """The case that opened every interface: the profile exported, so the range (LOCALHOST) was left as it was."""
    environment.setenv(PROFILE_ENV, str(FASTDDS_PROFILE))
    assert use_fastdds_profile() is None
    assert fastdds.os.environ[RANGE_ENV] == "SYSTEM_DEFAULT"


def test_a_loopback_profile_of_the_users_own_is_kept(environment: pytest.MonkeyPatch, tmp_path: Path) -> None:
    mine = profile(tmp_path)
    environment.setenv(PROFILE_ENV, str(mine))
    assert use_fastdds_profile() is None
    assert fastdds.os.environ[PROFILE_ENV] == str(mine)


def test_an_open_profile_is_replaced_and_the_process_says_why(
    environment: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mine = profile(tmp_path, allow="0.0.0.0")
    environment.setenv(PROFILE_ENV, str(mine))
    warning = use_fastdds_profile()
    assert fastdds.os.environ[PROFILE_ENV] == str(FASTDDS_PROFILE)
    assert warning is not None and f"{PROFILE_ENV}={mine} not used" in warning and "--network" in warning
    assert capsys.readouterr().err.strip() == f"warning: {warning}"


def test_an_open_profile_in_the_working_directory_is_skipped(environment: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Fast DDS loads ./DEFAULT_FASTRTPS_PROFILES.xml after the exported file: its default participant would win."""
    profile(tmp_path, builtin="true").rename(tmp_path / fastdds.WORKING_DIRECTORY_PROFILE)
    warning = use_fastdds_profile()
    assert fastdds.os.environ[SKIP_ENV] == "1"
    assert warning is not None and "DEFAULT_FASTRTPS_PROFILES.xml not loaded" in warning


def test_with_the_network_asked_for_the_users_profile_wins(environment: pytest.MonkeyPatch, tmp_path: Path) -> None:
    environment.setenv(fastdds.NETWORK_ENV, "1")
    assert use_fastdds_profile() is None
    assert fastdds.os.environ[PROFILE_ENV] == str(FASTDDS_NETWORK_PROFILE)
    mine = profile(tmp_path, allow="0.0.0.0")
    environment.setenv(PROFILE_ENV, str(mine))
    assert use_fastdds_profile() is None
    assert fastdds.os.environ[PROFILE_ENV] == str(mine)
