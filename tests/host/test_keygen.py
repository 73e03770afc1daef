"""`ropecam keygen` writes a key the protocol loads, private, and never overwrites one by accident."""

from __future__ import annotations

import stat

from ropecam.host.cli import main
from ropecam.shared.protocol import AuthConfig, load_key


def test_keygen_writes_a_private_loadable_key(tmp_path, capsys) -> None:
    path = tmp_path / "control.key"
    assert main(["keygen", str(path)]) == 0
    assert len(load_key(AuthConfig(key_file=path))) == 32  # type: ignore[arg-type]
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    first = path.read_text()
    assert main(["keygen", str(path)]) == 2
    assert "exists" in capsys.readouterr().err
    assert path.read_text() == first
    assert main(["keygen", str(path), "--force", "--bytes", "16"]) == 0
    assert len(load_key(AuthConfig(key_file=path))) == 16  # type: ignore[arg-type]
    assert main(["keygen", str(tmp_path / "short.key"), "--bytes", "8"]) == 2
