"""A digest of everything a frame produces, per real frame, tolerance and stamp: a speed change must not change one.

Each frame goes as a PointCloud2 (organized when its PCD is: H x W, else one row) through the pipeline (t = 1 and
2 cm, up to 5 planes, indices on the 2,000-point sample, as benchmarks/suite.py) and ``frame_messages``, three stamps
in a row (the tracker carries its ids from one to the next). Digested: the five output messages field by field (not
serialized: the CDR padding bytes are not set), the labels, the segmentation, the validity indices, the plane counts,
track ids and obstacles, and the diagnostic's message and key-values but ``processing_ms``. Floats by their bits.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/frame_digest.py [PCD ...] [--out FILE] [--check FILE]
(``--check``: compare with the lines another revision wrote; exit 1 on a difference)
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_frame import DATA  # noqa: E402
from pvbench.frame_calls import SETTINGS  # noqa: E402
from pvbench.node_e2e import cloud_message  # noqa: E402

from plane_validation.app.pipeline import FramePipeline, PipelineConfig  # noqa: E402
from plane_validation.core.allocator import reuse_freed_memory  # noqa: E402
from plane_validation.core.blas import limit_blas_threads  # noqa: E402
from plane_validation.core.kernels import warm  # noqa: E402
from plane_validation.formats.files import load_cloud  # noqa: E402
from plane_validation.ros.messages import frame_messages  # noqa: E402

TOLERANCES = (0.01, 0.02)
STAMPS = 3


def canonical(value) -> str:
    """``value`` (a message, dataclass, array, sequence or scalar) as text that differs when any of its bits do."""
    if hasattr(value, 'get_fields_and_field_types'):  # a ROS message
        fields = value.get_fields_and_field_types()
        return type(value).__name__ + '{' + ','.join(f'{f}:{canonical(getattr(value, f))}' for f in fields) + '}'
    if dataclasses.is_dataclass(value):
        fields = dataclasses.fields(value)
        return type(value).__name__ + '{' + ','.join(f'{f.name}:{canonical(getattr(value, f.name))}' for f in fields) \
            + '}'
    if isinstance(value, np.ndarray):
        return f'{value.dtype}{value.shape}:' + hashlib.sha256(np.ascontiguousarray(value).tobytes()).hexdigest()
    if isinstance(value, (bytes, bytearray, memoryview)) or type(value).__name__ == 'array':  # array.array
        return hashlib.sha256(bytes(value)).hexdigest()
    if isinstance(value, (list, tuple)):
        return '(' + ','.join(canonical(v) for v in value) + ')'
    if isinstance(value, (float, np.floating)):
        return float(value).hex()
    if isinstance(value, np.integer):
        return str(int(value))
    return repr(value)


def frame_digests(path: str) -> dict[str, str]:
    """Per tolerance and stamp, the digest of the frame ``path`` through the pipeline and its messages."""
    points, shape = load_cloud(path)
    msg = cloud_message(points, *(shape or (1, len(points))))
    out = {}
    for t in TOLERANCES:
        pipe = FramePipeline(PipelineConfig(**{**SETTINGS, 'tolerance': t}))
        for i in range(STAMPS):
            msg.header.stamp.sec = i + 1
            result = pipe.process_cloud(msg)
            messages = frame_messages(msg.header, result, 'pv')
            for kv in messages['diagnostics'].status[0].values:
                if kv.key == 'processing_ms':  # a timing, not a result
                    kv.value = ''
            parts = [canonical(messages[key]) for key in sorted(messages)]
            parts += [canonical(v) for v in (result.labels, result.segmentation, result.indices, result.plane_counts,
                                              result.plane_ids, result.obstacles, result.image_labels,
                                              result.diagnostic.message)]
            parts.append(canonical([kv for kv in result.diagnostic.values if kv[0] != 'processing_ms']))
            out[f'{Path(path).name} t={t} stamp={i + 1}'] = hashlib.sha256('|'.join(parts).encode()).hexdigest()[:32]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('clouds', nargs='*', default=[str(p) for p in sorted(DATA.glob('*.pcd'))])
    parser.add_argument('--out', type=Path, help='write the lines here too')
    parser.add_argument('--check', type=Path, help="another revision's lines: exit 1 unless these are the same")
    args = parser.parse_args()
    limit_blas_threads()
    reuse_freed_memory()
    warm()
    lines = []
    for path in args.clouds:
        for key, digest in frame_digests(path).items():
            lines.append(f'{key} {digest}')
            print(lines[-1], flush=True)
    if args.out:
        args.out.write_text('\n'.join(lines) + '\n')
    if args.check:
        expected = args.check.read_text().splitlines()
        differ = [a.rsplit(' ', 1)[0] for a, b in zip(lines, expected) if a != b]
        if differ or len(lines) != len(expected):
            print(f'DIFFERENT: {len(differ)} of {len(lines)} ({", ".join(differ[:5])}); {len(expected)} expected')
            sys.exit(1)
        print(f'identical: {len(lines)} frames')


if __name__ == '__main__':
    main()
