#!/usr/bin/python3
"""TSDF integration speed and surface error: genscene against Open3D's ScalableTSDFVolume.

Both integrate the same frames of a genscene-synth folder at the ground-truth poses with the same
voxel size and truncation; both surfaces are meshed (genscene-mesh; Open3D's
extract_triangle_mesh) and compared with the folder's mesh_gt.ply (distance of points sampled on
each reconstruction to the true surface).

Usage: /usr/bin/python3 bench/compare_open3d_fusion.py SEQ_FOLDER [--build build] [--voxel 0.01]
       [--trunc 0.04]   (Debian's python3-open3d lives under /usr/bin/python3)
"""
import argparse
import json
import os
import subprocess
import tempfile
import time

import numpy as np
import open3d as o3d


def read_list(path):
    rows = []
    for line in open(path):
        line = line.strip()
        if line and not line.startswith("#"):
            rows.append(line.split())
    return rows


def surface_error(mesh, gt_scene, gt_points, samples=200000):
    """Accuracy (points sampled on the reconstruction against the true surface: RMS, mean, p90)
    and completeness (the share of points sampled on the true surface that lie within 1 cm of the
    reconstruction; the true mesh also holds surfaces no camera saw, so the figure compares the
    two reconstructions, it does not reach 100 %)."""
    points = mesh.sample_points_uniformly(samples)
    query = o3d.core.Tensor(np.asarray(points.points), dtype=o3d.core.Dtype.Float32)
    d = gt_scene.compute_distance(query).numpy()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    back = scene.compute_distance(gt_points).numpy()
    return (float(np.sqrt(np.mean(d * d))), float(np.mean(d)), float(np.percentile(d, 90)),
            float(100.0 * np.mean(back < 0.01)))


EXTRA = os.environ.get("GS_EXTRA", "").split()


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder")
    ap.add_argument("--build", default="build")
    ap.add_argument("--voxel", type=float, default=0.01)
    ap.add_argument("--trunc", type=float, default=0.04)
    ap.add_argument("--threads", type=int, default=0)
    a = ap.parse_args()

    fx, fy, cx, cy, w, h = open(os.path.join(a.folder, "intrinsics.txt")).read().split()[:6]
    intr = o3d.camera.PinholeCameraIntrinsic(int(w), int(h), float(fx), float(fy), float(cx), float(cy))
    rgb = read_list(os.path.join(a.folder, "rgb.txt"))
    depth = read_list(os.path.join(a.folder, "depth.txt"))
    gt = {row[0]: [float(x) for x in row[1:]] for row in read_list(os.path.join(a.folder, "groundtruth.txt"))}
    gt_mesh = o3d.t.geometry.TriangleMesh.from_legacy(o3d.io.read_triangle_mesh(os.path.join(a.folder, "mesh_gt.ply")))
    gt_scene = o3d.t.geometry.RaycastingScene()
    gt_scene.add_triangles(gt_mesh)
    gt_points = o3d.core.Tensor(np.asarray(gt_mesh.to_legacy().sample_points_uniformly(200000).points),
                                dtype=o3d.core.Dtype.Float32)

    # Open3D: decode first (not timed), then time integrate() alone.
    frames = []
    for (t, cpath), (_, dpath) in zip(rgb, depth):
        color = o3d.io.read_image(os.path.join(a.folder, cpath))
        dimg = o3d.io.read_image(os.path.join(a.folder, dpath))
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
            color, dimg, depth_scale=5000.0, depth_trunc=6.0, convert_rgb_to_intensity=False)
        tx, ty, tz, qx, qy, qz, qw = gt[t]
        pose = np.eye(4)
        pose[:3, :3] = o3d.geometry.get_rotation_matrix_from_quaternion([qw, qx, qy, qz])
        pose[:3, 3] = [tx, ty, tz]
        frames.append((rgbd, np.linalg.inv(pose)))
    volume = o3d.pipelines.integration.ScalableTSDFVolume(
        voxel_length=a.voxel, sdf_trunc=a.trunc, color_type=o3d.pipelines.integration.TSDFVolumeColorType.RGB8)
    start = time.perf_counter()
    for rgbd, extrinsic in frames:
        volume.integrate(rgbd, intr, extrinsic)
    o3d_seconds = time.perf_counter() - start
    start = time.perf_counter()
    o3d_mesh = volume.extract_triangle_mesh()
    o3d_mesh_seconds = time.perf_counter() - start

    # genscene: the same frames at the same poses (tracking = known).
    with tempfile.TemporaryDirectory() as ws:
        env = dict(os.environ)
        subprocess.run([os.path.join(a.build, "apps", "genscene-fuse"), "--input", a.folder, ws, "--tracking", "known",
                        "--voxel-size", str(a.voxel), "--truncation", str(a.trunc), "--range-max", "6", *EXTRA,
                        "--threads", str(a.threads)], check=True, env=env, capture_output=True)
        report = json.load(open(os.path.join(ws, "fusion.json")))
        gs_seconds = sum(f["ms_integrate"] for f in report["frames"]) / 1e3
        start = time.perf_counter()
        subprocess.run([os.path.join(a.build, "apps", "genscene-mesh"), ws, "--threads", str(a.threads)],
                       check=True, capture_output=True)
        gs_mesh_seconds = time.perf_counter() - start  # includes process start and PLY I/O
        gs_mesh = o3d.io.read_triangle_mesh(os.path.join(ws, "mesh.ply"))
        blocks = report["summary"]["blocks"]

    n = len(frames)
    print(f"{n} frames {w}x{h}, voxel {a.voxel} m, truncation {a.trunc} m, threads {a.threads or 'all'}")
    print(f"{'':10} {'integrate fps':>14} {'mesh s':>8} {'vertices':>9} {'triangles':>10} {'RMS mm':>8} {'mean mm':>8} {'p90 mm':>8} {'complete %':>10}")
    for name, seconds, mesh_s, mesh in (("Open3D", o3d_seconds, o3d_mesh_seconds, o3d_mesh),
                                        ("genscene", gs_seconds, gs_mesh_seconds, gs_mesh)):
        rms, mean, p90, complete = surface_error(mesh, gt_scene, gt_points)
        print(f"{name:10} {n / seconds:14.1f} {mesh_s:8.2f} {len(mesh.vertices):9d} {len(mesh.triangles):10d} "
              f"{1e3 * rms:8.2f} {1e3 * mean:8.2f} {1e3 * p90:8.2f} {complete:10.2f}")
    print(f"integration speed ratio genscene / Open3D: {o3d_seconds / gs_seconds:.2f}x; genscene blocks: {blocks}")


if __name__ == "__main__":
    main()
