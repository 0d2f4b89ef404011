"""The caster URL (a password in it refused) and the password file's permission check."""

from __future__ import annotations

import pytest

from ntrip_client.caster_url import CasterUrl, parse_caster_url, read_password


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "http://caster.example:2101/AAU00DNK",
            CasterUrl("http", "", "caster.example", 2101, "AAU00DNK"),
        ),
        (
            "https://rover@caster.example/MP",
            CasterUrl("https", "rover", "caster.example", 2101, "MP"),
        ),
        ("http://a%40b@127.0.0.1:8080/", CasterUrl("http", "a@b", "127.0.0.1", 8080, "")),
        ("http://caster.example", CasterUrl("http", "", "caster.example", 2101, "")),
    ],
)
def test_urls_parse(text, expected):
    assert parse_caster_url(text) == expected


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("ftp://caster/MP", "expected http://"),
        ("caster:2101/MP", "expected http://"),
        ("http:///MP", "no host"),
        ("http://caster:99999/MP", "port"),
        ("http://caster/MP?x=1", "no query"),
        ("http://caster/A/B", "one name"),
    ],
)
def test_bad_urls_say_what_is_wrong(text, message):
    with pytest.raises(ValueError, match=message):
        parse_caster_url(text)


def test_a_password_in_the_url_is_refused_and_never_echoed():
    with pytest.raises(ValueError) as refused:
        parse_caster_url("http://rover:hunter2@caster.example/MP")
    assert "NTRIP_PASSWORD" in str(refused.value) and "password file" in str(refused.value)
    assert "hunter2" not in str(refused.value)


def test_display_has_user_host_port_mountpoint():
    url = parse_caster_url("https://rover@caster.example/MP")
    assert str(url) == url.display == "https://rover@caster.example:2101/MP"


def test_password_from_the_environment_or_none():
    assert read_password({"NTRIP_PASSWORD": "pw"}, None) == "pw"
    assert read_password({}, None) == ""


def test_password_file_wins_and_loses_its_newline(tmp_path):
    path = tmp_path / "pw"
    path.write_text("from-file\n")
    path.chmod(0o600)
    assert read_password({"NTRIP_PASSWORD": "from-env"}, str(path)) == "from-file"
    path.chmod(0o400)
    assert read_password({}, str(path)) == "from-file"


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o604, 0o660])
def test_password_file_readable_by_others_is_refused(tmp_path, mode):
    path = tmp_path / "pw"
    path.write_text("secret\n")
    path.chmod(mode)
    with pytest.raises(ValueError, match=f"chmod 600 {path}"):
        read_password({}, str(path))


def test_password_file_missing_or_not_a_file(tmp_path):
    with pytest.raises(ValueError, match=str(tmp_path / "none")):
        read_password({}, str(tmp_path / "none"))
    with pytest.raises(ValueError, match="not a regular file"):
        read_password({}, str(tmp_path))
