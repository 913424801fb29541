#!/usr/bin/env python3
"""Marching cubes: genscene against skimage and Open3D, counts and times side by side (issue 5).

1. Dense grids: runs bench_marching_cubes --dump, which meshes gyroid volumes and writes each grid
   as .npy, then times skimage.measure.marching_cubes (Lewiner) on the same grids at level 0.
2. Fused scene (optional, --tum DIR --tsdf WS/tsdf.gsv): Open3D fuses the TUM-layout folder into a
   ScalableTSDFVolume with the voxel size and truncation of our tsdf.gsv and times
   extract_triangle_mesh; bench_marching_cubes --tsdf times ExtractMesh on our tsdf.gsv (fused
   from the same folder by genscene-fuse) in-process, like Open3D's call, and prints its
   decimation table. The volumes are fused by different code, so counts agree only roughly.
3. Same volume (with --tsdf): our tsdf.gsv's blocks (8^3 voxels, as Open3D's) copied into an
   Open3D tensor VoxelBlockGrid (tsdf = sdf / truncation, weight), whose extract_triangle_mesh is
   timed on exactly the voxels ExtractMesh meshes (block keys, voxel order and values carried
   over; voxels of weight 0 count as unobserved in both).

Each time is the best of --repeat runs. Run by hand, e.g.
  python3 bench/compare_marching_cubes.py --build build --sizes 64 128
  python3 bench/compare_marching_cubes.py --build build --tum ws/input --tsdf ws/tsdf.gsv
"""
import argparse
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import time


def best_time(fn, repeat):
    best, result = float("inf"), None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best, result


def dense_grids(args, workdir):
    import numpy as np
    from skimage import measure

    bench = os.path.join(args.build, "bench", "bench_marching_cubes")
    extra = ["--tsdf", args.tsdf] if args.tsdf else []
    text = subprocess.run([bench, "--dump", workdir] + extra + [str(n) for n in args.sizes], check=True,
                          capture_output=True, text=True).stdout
    args.fused_text = text[text.find("\nFused volume"):] if args.tsdf else ""
    ours = {}
    with open(os.path.join(workdir, "genscene_mc.txt")) as f:
        for line in f:
            n, threads, verts, tris, seconds = line.split()
            ours[(int(n), int(threads))] = (int(verts), int(tris), float(seconds))
    sizes = sorted({n for n, _ in ours})
    print("Dense gyroid grids, level 0 (genscene: best of 3 after a warm-up; skimage: best of %d)" % args.repeat)
    print("%6s %12s | %10s %10s %9s %9s | %10s %10s %9s | %8s" % (
        "N", "cells", "gs verts", "gs tris", "gs 1t ms", "gs Nt ms", "sk verts", "sk tris", "sk ms",
        "speedup"))
    for n in sizes:
        grid = np.load(os.path.join(workdir, "gyroid_%d.npy" % n))
        seconds, (verts, faces, _, _) = best_time(lambda: measure.marching_cubes(grid, level=0.0), args.repeat)
        one = ours[(n, 1)]
        many = max(((k, v) for k, v in ours.items() if k[0] == n), key=lambda kv: kv[0][1])
        print("%6d %12d | %10d %10d %9.1f %9.1f | %10d %10d %9.1f | %7.1fx" % (
            n, n ** 3, one[0], one[1], one[2] * 1e3, many[1][2] * 1e3, len(verts), len(faces), seconds * 1e3,
            seconds / many[1][2]))
    print("(gs Nt: all threads; speedup: skimage time / genscene all-threads time)")


def read_gsv_header(path):
    with open(path, "rb") as f:
        head = f.read(8 + 8 + 8 + 4 + 24 + 8)
    if head[:8] != b"GSTSDF01":
        sys.exit("%s: not a genscene TSDF volume" % path)
    voxel_size, truncation = struct.unpack_from("<dd", head, 8)
    return voxel_size, truncation


def read_list(path):
    rows = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line and not line.startswith("#"):
                rows.append(line.split())
    return rows


def nearest(rows, stamp, max_dt=0.02):
    best = min(rows, key=lambda r: abs(float(r[0]) - stamp))
    return best if abs(float(best[0]) - stamp) <= max_dt else None


def fused_scene(args, workdir):
    import numpy as np
    import open3d as o3d

    voxel_size, truncation = read_gsv_header(args.tsdf)
    fx, fy, cx, cy, width, height = [float(x) for x in read_list(os.path.join(args.tum, "intrinsics.txt"))[0][:6]]
    intrinsic = o3d.camera.PinholeCameraIntrinsic(int(width), int(height), fx, fy, cx, cy)
    depth_rows = read_list(os.path.join(args.tum, "depth.txt"))
    rgb_rows = read_list(os.path.join(args.tum, "rgb.txt"))
    pose_rows = read_list(os.path.join(args.tum, "groundtruth.txt"))
    volume = o3d.pipelines.integration.ScalableTSDFVolume(
        voxel_length=voxel_size, sdf_trunc=truncation, color_type=o3d.pipelines.integration.TSDFVolumeColorType.RGB8)
    frames = 0
    for stamp, depth_file in depth_rows:
        rgb, pose = nearest(rgb_rows, float(stamp)), nearest(pose_rows, float(stamp))
        if rgb is None or pose is None:
            continue
        color = o3d.io.read_image(os.path.join(args.tum, rgb[1]))
        depth = o3d.io.read_image(os.path.join(args.tum, depth_file))
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
            color, depth, depth_scale=args.depth_scale, depth_trunc=args.max_depth, convert_rgb_to_intensity=False)
        tx, ty, tz, qx, qy, qz, qw = [float(x) for x in pose[1:8]]
        world_from_camera = np.eye(4)
        world_from_camera[:3, :3] = o3d.geometry.get_rotation_matrix_from_quaternion([qw, qx, qy, qz])
        world_from_camera[:3, 3] = [tx, ty, tz]
        volume.integrate(rgbd, intrinsic, np.linalg.inv(world_from_camera))
        frames += 1
    o3d_seconds, mesh = best_time(volume.extract_triangle_mesh, args.repeat)

    print("\nFused scene %s (%d frames, voxel %.4f m, truncation %.4f m); best of %d" % (
        args.tum, frames, voxel_size, truncation, args.repeat))
    print_against_ours("Open3D ScalableTSDFVolume.extract_triangle_mesh", len(mesh.vertices), len(mesh.triangles),
                       o3d_seconds, workdir)
    print(args.fused_text)


def print_against_ours(label, vertices, triangles, seconds, workdir):
    """Open3D's row, ExtractMesh's (bench_marching_cubes --tsdf wrote it to genscene_fused.txt), the speedup."""
    with open(os.path.join(workdir, "genscene_fused.txt")) as f:
        threads, gs_verts, gs_tris, gs_seconds = f.read().split()
    print("%-48s %10s %10s %10s" % ("", "vertices", "triangles", "ms"))
    print("%-48s %10d %10d %10.1f" % (label, vertices, triangles, seconds * 1e3))
    print("%-48s %10s %10s %10.1f" % ("genscene ExtractMesh (%s threads)" % threads, gs_verts, gs_tris,
                                      float(gs_seconds) * 1e3))
    print("speedup: %.1fx" % (seconds / float(gs_seconds)))


def read_gsv_blocks(path):
    """The blocks of a tsdf.gsv (header: read_gsv_header): i32 key[3], 512 voxels of 5 floats."""
    import numpy as np
    with open(path, "rb") as f:
        data = f.read()
    (count,) = struct.unpack_from("<Q", data, 52)
    block = np.dtype([("key", "<i4", 3), ("voxels", "<f4", (512, 5))])
    return np.frombuffer(data, dtype=block, count=count, offset=60)


def same_volume(args):
    import numpy as np
    import open3d as o3d
    import open3d.core as o3c

    voxel_size, truncation = read_gsv_header(args.tsdf)
    blocks = read_gsv_blocks(args.tsdf)
    device = o3c.Device("CPU:0")
    vbg = o3d.t.geometry.VoxelBlockGrid(
        attr_names=("tsdf", "weight"), attr_dtypes=(o3c.float32, o3c.float32), attr_channels=((1), (1)),
        voxel_size=voxel_size, block_resolution=8, block_count=len(blocks) + 16, device=device)
    keys = o3c.Tensor(np.ascontiguousarray(blocks["key"]), dtype=o3c.int32, device=device)
    buf_indices, masks = vbg.hashmap().activate(keys)
    assert masks.numpy().all(), "duplicate block keys"
    # Both lay a block's voxels out x fastest, then y, then z.
    voxels = blocks["voxels"]
    tsdf = (voxels[:, :, 0] / truncation).reshape(-1, 8, 8, 8, 1).astype(np.float32)
    weight = voxels[:, :, 1].reshape(-1, 8, 8, 8, 1).astype(np.float32)
    index = buf_indices.to(o3c.int64)
    vbg.attribute("tsdf")[index] = o3c.Tensor(tsdf, device=device)
    vbg.attribute("weight")[index] = o3c.Tensor(weight, device=device)
    o3d_seconds, mesh = best_time(lambda: vbg.extract_triangle_mesh(weight_threshold=1e-6), args.repeat)
    print("\nSame volume %s (%d blocks of 8^3 voxels, voxel %.4f m) copied into Open3D; best of %d" % (
        args.tsdf, len(blocks), voxel_size, args.repeat))
    print_against_ours("Open3D VoxelBlockGrid.extract_triangle_mesh", mesh.vertex.positions.shape[0],
                       mesh.triangle.indices.shape[0], o3d_seconds, args.workdir)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", default="build", help="build folder with bench/ and apps/")
    parser.add_argument("--sizes", type=int, nargs="*", default=[64, 128, 192], help="dense grid sizes N (N^3)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--tum", help="TUM-layout folder (rgb.txt, depth.txt, groundtruth.txt, intrinsics.txt)")
    parser.add_argument("--tsdf", help="our tsdf.gsv fused from the same folder")
    parser.add_argument("--depth-scale", type=float, default=5000.0, help="depth PNG units per metre")
    parser.add_argument("--max-depth", type=float, default=4.0, help="metres; deeper depth is ignored by Open3D")
    args = parser.parse_args()
    if bool(args.tum) != bool(args.tsdf):
        parser.error("--tum and --tsdf go together")
    workdir = tempfile.mkdtemp(prefix="genscene-mc-compare-")
    args.workdir = workdir
    try:
        dense_grids(args, workdir)
        if args.tum:
            fused_scene(args, workdir)
        if args.tsdf:
            same_volume(args)
    finally:
        shutil.rmtree(workdir, ignore_errors=True)


if __name__ == "__main__":
    main()
