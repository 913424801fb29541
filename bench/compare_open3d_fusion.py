#!/usr/bin/python3
"""TSDF integration speed and surface error: genscene against Open3D's ScalableTSDFVolume.

Both integrate the same frames of a genscene-synth folder at the ground-truth poses with the same
voxel size and truncation; both surfaces are meshed (genscene-mesh; Open3D's
extract_triangle_mesh) and compared with the folder's mesh_gt.ply (distance of points sampled on
each reconstruction to the true surface).

Usage: /usr/bin/python3 bench/compare_open3d_fusion.py SEQ_FOLDER [--build build] [--voxel 0.01]
       [--trunc 0.04]   (Debian's python3-open3d lives under /usr/bin/python3)

--odometry FOLDER...: tracking + fusion on recordings with ground truth (TUM layout with rgb.txt,
depth.txt and groundtruth.txt, or 7-Scenes' frame-NNNNNN.{color,depth}.png and .pose.txt with
camera-intrinsics.txt beside them): Open3D's hybrid RGB-D odometry (frame to frame,
RGBDOdometryJacobianFromHybridTerm, its default options) and ScalableTSDFVolume integration at the
poses it gives, each timed after decoding, against genscene's tracking + fusion at its defaults
(build/bench/bench_fusion, run in the same invocation: per-step fps and the whole of
ProcessFrame); ATE of each (translation RMSE after a rigid Horn alignment, as genscene's).
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


def quaternion_pose(values):
    tx, ty, tz, qx, qy, qz, qw = values
    pose = np.eye(4)
    pose[:3, :3] = o3d.geometry.get_rotation_matrix_from_quaternion([qw, qx, qy, qz])
    pose[:3, 3] = [tx, ty, tz]
    return pose


def nearest(stamps, t):
    """Index of the time stamp nearest t (stamps sorted)."""
    i = int(np.searchsorted(stamps, t))
    if i == len(stamps) or (i > 0 and t - stamps[i - 1] < stamps[i] - t):
        i -= 1
    return i


def read_recording(folder):
    """(intrinsic, depth scale, [(colour path, depth path, world_from_camera)]) of a TUM or
    7-Scenes folder; TUM's depth images are paired with the nearest colour image, and the ground
    truth is taken at the colour image's time (positions interpolated), as genscene's reader and
    its ATE do."""
    frames_dir = os.path.join(folder, "rgbd-frames")
    if os.path.isdir(frames_dir):
        k = np.loadtxt(os.path.join(folder, "camera-intrinsics.txt"))
        names = sorted(f[:-len(".color.png")] for f in os.listdir(frames_dir) if f.endswith(".color.png"))
        frames = [(os.path.join(frames_dir, n + ".color.png"), os.path.join(frames_dir, n + ".depth.png"),
                   np.loadtxt(os.path.join(frames_dir, n + ".pose.txt"))) for n in names]
        first = o3d.io.read_image(frames[0][1])
        h, w = np.asarray(first).shape[:2]
        return o3d.camera.PinholeCameraIntrinsic(w, h, k[0, 0], k[1, 1], k[0, 2], k[1, 2]), 1000.0, frames
    rgb = read_list(os.path.join(folder, "rgb.txt"))
    depth = read_list(os.path.join(folder, "depth.txt"))
    gt = read_list(os.path.join(folder, "groundtruth.txt"))
    present = lambda rows: [r for r in rows if os.path.exists(os.path.join(folder, r[1]))]
    rgb, depth = present(rgb), present(depth)
    rgb_t = np.array([float(r[0]) for r in rgb])
    gt_t = np.array([float(r[0]) for r in gt])
    gt_xyz = np.array([[float(x) for x in r[1:4]] for r in gt])
    frames = []
    for t, dpath in depth:
        c = rgb[nearest(rgb_t, float(t))]
        # The ground truth at the frame's (colour) time stamp, as genscene's ATE pairs it: the
        # position interpolated between the bracketing poses (the rotation of the nearest one;
        # the ATE uses positions only).
        g = gt[nearest(gt_t, float(c[0]))]
        pose = quaternion_pose([float(x) for x in g[1:8]])
        pose[:3, 3] = [np.interp(float(c[0]), gt_t, gt_xyz[:, k]) for k in range(3)]
        frames.append((os.path.join(folder, c[1]), os.path.join(folder, dpath), pose))
    first = np.asarray(o3d.io.read_image(frames[0][1]))
    h, w = first.shape[:2]
    name = os.path.basename(os.path.normpath(folder))
    if "fr1" in name:  # TUM's freiburg1 camera (genscene's tum1)
        intr = o3d.camera.PinholeCameraIntrinsic(w, h, 517.3, 516.5, 318.6, 255.3)
    else:
        fx, fy, cx, cy = open(os.path.join(folder, "intrinsics.txt")).read().split()[:4]
        intr = o3d.camera.PinholeCameraIntrinsic(w, h, float(fx), float(fy), float(cx), float(cy))
    return intr, 5000.0, frames


def ate(estimated, truth):
    """Translation RMSE after the rigid (rotation + translation) alignment of estimated to truth."""
    p = np.array([e[:3, 3] for e in estimated])
    q = np.array([t[:3, 3] for t in truth])
    pm, qm = p.mean(0), q.mean(0)
    u, _, vt = np.linalg.svd((q - qm).T @ (p - pm))
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    r = u @ d @ vt
    aligned = (r @ (p - pm).T).T + qm
    return float(np.sqrt(np.mean(np.sum((aligned - q) ** 2, axis=1))))


def odometry(folders, build, voxel, trunc):
    print(f"{'recording':28} {'frames':>6} | {'O3D odom fps':>12} {'O3D integ fps':>13} {'O3D both fps':>12} "
          f"{'O3D ATE cm':>10} | {'gs fps':>7} {'gs wall fps':>11} {'gs ATE cm':>9} | ATE ratio")
    for folder in folders:
        intr, scale, paths = read_recording(folder)
        rgbds = []
        for cpath, dpath, _ in paths:  # decoding is not timed
            rgbds.append(o3d.geometry.RGBDImage.create_from_color_and_depth(
                o3d.io.read_image(cpath), o3d.io.read_image(dpath), depth_scale=scale, depth_trunc=6.0,
                convert_rgb_to_intensity=True))
        option = o3d.pipelines.odometry.OdometryOption()
        jacobian = o3d.pipelines.odometry.RGBDOdometryJacobianFromHybridTerm()
        poses = [paths[0][2]]
        start = time.perf_counter()
        for i in range(1, len(rgbds)):
            # source = frame i, target = frame i - 1: the result maps i's points into i - 1's frame.
            ok, target_from_source, _ = o3d.pipelines.odometry.compute_rgbd_odometry(
                rgbds[i], rgbds[i - 1], intr, np.eye(4), jacobian, option)
            poses.append(poses[-1] @ (target_from_source if ok else np.eye(4)))
        odom_seconds = time.perf_counter() - start
        volume = o3d.pipelines.integration.ScalableTSDFVolume(
            voxel_length=voxel, sdf_trunc=trunc, color_type=o3d.pipelines.integration.TSDFVolumeColorType.RGB8)
        colour = [o3d.geometry.RGBDImage.create_from_color_and_depth(
            o3d.io.read_image(c), o3d.io.read_image(d), depth_scale=scale, depth_trunc=6.0,
            convert_rgb_to_intensity=False) for c, d, _ in paths]
        start = time.perf_counter()
        for rgbd, pose in zip(colour, poses):
            volume.integrate(rgbd, intr, np.linalg.inv(pose))
        integ_seconds = time.perf_counter() - start
        o3d_ate = ate(poses, [p[2] for p in paths])
        out = subprocess.run([os.path.join(build, "bench", "bench_fusion"), folder, "--copies", "0"],
                             check=True, capture_output=True, text=True).stdout
        row = [l for l in out.splitlines() if "|" in l and not l.startswith("sequence")][-1]
        cells = row.split("|")
        gs_fps, gs_wall = (float(x) for x in cells[1].split()[-2:])
        gs_ate = float(cells[2])
        n = len(rgbds)
        name = os.path.basename(os.path.normpath(folder))
        print(f"{name:28} {n:6d} | {(n - 1) / odom_seconds:12.1f} {n / integ_seconds:13.1f} "
              f"{n / (odom_seconds + integ_seconds):12.1f} {100 * o3d_ate:10.3f} | {gs_fps:7.1f} {gs_wall:11.1f} "
              f"{gs_ate:9.3f} | {gs_ate / (100 * o3d_ate):.2f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", nargs="+")
    ap.add_argument("--odometry", action="store_true",
                    help="tracking + fusion on recordings with ground truth (see the top of the file)")
    ap.add_argument("--build", default="build")
    ap.add_argument("--voxel", type=float, default=0.01)
    ap.add_argument("--trunc", type=float, default=0.04)
    ap.add_argument("--threads", type=int, default=0)
    a = ap.parse_args()
    if a.odometry:
        odometry(a.folder, a.build, a.voxel, a.trunc)
        return
    if len(a.folder) != 1:
        ap.error("one folder without --odometry")
    a.folder = a.folder[0]

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
