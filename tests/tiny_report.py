"""One tiny report run shared by the report and notebook tests (a module-level cache, so one
pytest session builds it once)."""

from pathlib import Path

_CACHE: dict[str, Path] = {}


def tiny_report(tmp_path_factory) -> Path:
    """The output folder of ``mjx-balance report --scale tiny`` (through the command line)."""
    if "out" not in _CACHE:
        from mjx_balance.cli import main

        out = tmp_path_factory.mktemp("tiny_report")
        assert main(["report", "--scale", "tiny", "--out", str(out)]) == 0
        _CACHE["out"] = out
    return _CACHE["out"]
