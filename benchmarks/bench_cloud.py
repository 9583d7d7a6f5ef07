"""Time PointCloud2 -> numpy conversion on a 640x480 organized float32 x,y,z,rgb cloud (no ROS needed).

Run: .venv/bin/python benchmarks/bench_cloud.py
"""
import array

import numpy as np

from plane_validation.formats.pointcloud2 import structured_array, xyz_array


def main(repeats: int = 50) -> None:
    """Print xyz_array timings on a 640x480 organized float32 x,y,z,rgb cloud (no ROS needed)."""
    import time
    from types import SimpleNamespace

    height, width, step = 480, 640, 16
    rng = np.random.default_rng(0)
    points = rng.normal(size=(height * width, 4)).astype('<f4')
    points[rng.random(height * width) < 0.1, :3] = np.nan
    fields = [SimpleNamespace(name=n, offset=4 * i, datatype=7, count=1)
              for i, n in enumerate(('x', 'y', 'z', 'rgb'))]
    as_array = lambda b: array.array('B', b)  # noqa: E731  (rclpy)
    as_ndarray = lambda b: np.frombuffer(b, np.uint8)  # noqa: E731  (rosbags)
    for label, row_pad, data_of in (('array.array', 0, as_array), ('ndarray', 0, as_ndarray),
                                    ('ndarray, row padding', 64, as_ndarray)):
        rows = np.zeros((height, width * step + row_pad), np.uint8)
        rows[:, :width * step] = points.view(np.uint8).reshape(height, width * step)
        msg = SimpleNamespace(header=None, height=height, width=width, fields=fields,
                              is_bigendian=False, point_step=step, row_step=width * step + row_pad,
                              data=data_of(rows.tobytes()), is_dense=False)
        for dtype in (np.float64, np.float32):
            xyz_array(msg, dtype=dtype)
            start = time.perf_counter()
            for _ in range(repeats):
                xyz_array(msg, dtype=dtype)
            ms = (time.perf_counter() - start) / repeats * 1e3
            print(f'xyz_array 640x480 x,y,z,rgb float32 [{label}] -> {np.dtype(dtype)}: '
                  f'{ms:.2f} ms')
        start = time.perf_counter()
        for _ in range(repeats):
            structured_array(msg)
        ms = (time.perf_counter() - start) / repeats * 1e3
        print(f'structured_array [{label}]: {ms:.3f} ms')


if __name__ == '__main__':
    main()
