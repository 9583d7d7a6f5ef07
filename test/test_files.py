"""Point files for the command line: PCD ascii/binary (written here), .npy, text; and the detect command."""
import numpy as np
import pytest

from plane_validation import scenes
from plane_validation.cli import main as cli_main
from plane_validation.files import load_points

POINTS = scenes.corner(600, 1.0, scale=0.01, seed=2).points


def _pcd_header(data: str, n: int, *, version: str = '0.7') -> bytes:
    return (f'# .PCD v{version} - written by the test\nVERSION {version}\nFIELDS x y z rgb\nSIZE 4 4 4 4\n'
            f'TYPE F F F U\nCOUNT 1 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\n'
            f'DATA {data}\n').encode()


@pytest.mark.parametrize('version', ['0.7', '.5'])
def test_pcd_ascii_and_binary(tmp_path, version):
    ascii_path = tmp_path / 'a.pcd'
    rows = '\n'.join(f'{x:.7g} {y:.7g} {z:.7g} 4278190080' for x, y, z in POINTS)
    ascii_path.write_bytes(_pcd_header('ascii', len(POINTS), version=version) + rows.encode() + b'\n')
    np.testing.assert_allclose(load_points(ascii_path), POINTS, atol=1e-6)

    binary_path = tmp_path / 'b.pcd'
    records = np.zeros(len(POINTS), dtype=[('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('rgb', '<u4')])
    records['x'], records['y'], records['z'] = POINTS.T
    binary_path.write_bytes(_pcd_header('binary', len(POINTS), version=version) + records.tobytes())
    np.testing.assert_array_equal(load_points(binary_path), POINTS.astype(np.float32).astype(np.float64))


def test_text_and_npy(tmp_path):
    np.save(tmp_path / 'p.npy', POINTS)
    np.savetxt(tmp_path / 'p.xyz', POINTS)
    np.savetxt(tmp_path / 'p.csv', np.column_stack([POINTS, np.ones(len(POINTS))]), delimiter=',')
    for name in ('p.npy', 'p.xyz', 'p.csv'):
        np.testing.assert_allclose(load_points(tmp_path / name), POINTS)


@pytest.mark.parametrize('content, words', [
    (b'VERSION 0.7\nFIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\n'
     b'DATA ascii\n1 2 3\n', 'no x, y, z'),
    (b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n', 'no DATA'),
    (b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 10\nHEIGHT 1\nPOINTS 10\nDATA binary\n'
     + bytes(20), 'need'),
])
def test_malformed_pcd_is_a_clear_error(tmp_path, content, words):
    path = tmp_path / 'bad.pcd'
    path.write_bytes(content)
    with pytest.raises(ValueError, match=words):
        load_points(path)


def test_detect_command(tmp_path, capsys):
    np.save(tmp_path / 'corner.npy', POINTS)
    assert cli_main(['detect', str(tmp_path / 'corner.npy'), '--png', str(tmp_path / 'c.png')]) == 0
    out = capsys.readouterr().out
    assert '3 plane(s)' in out and 'tuned tolerance' in out and 'reliable' in out
    assert (tmp_path / 'c.png').stat().st_size > 10_000
    assert cli_main(['detect', str(tmp_path / 'corner.npy'), '--tolerance', '0.02']) == 0
    assert '3 plane(s), tolerance 0.02 m' in capsys.readouterr().out
    assert cli_main(['detect', str(tmp_path / 'missing.pcd')]) == 2
    assert 'no such file' in capsys.readouterr().err
    assert cli_main(['tune', str(tmp_path / 'corner.npy')]) == 0
    assert 'chosen t =' in capsys.readouterr().out
