"""Each function of the Python module against the CLI on the same inputs, and bad inputs."""
import fcntl
import json
import os
import pathlib
import shutil
import signal
import threading
import time

import numpy as np
import pytest

import ffloc
from conftest import localize_with_cli, without_timings


# Datasets

def test_load_dataset_gives_the_frames_the_cli_maps(scene_dir, cli_map):
    scene = ffloc.load_dataset(str(scene_dir))
    assert scene.format == "manifest" or scene.format
    mapping = [scene.frames[i] for i in scene.mapping_indices()]
    assert [frame.split for frame in mapping] == ["mapping"] * len(mapping)
    # The CLI's map holds the mapping frames by name, with their poses.
    cli = ffloc.Map.load(str(cli_map))
    assert cli.names == [frame.name for frame in mapping]
    for frame, pose in zip(mapping, cli.camera_to_world):
        np.testing.assert_array_equal(frame.camera_to_world, pose)
    frame = mapping[0]
    assert frame.camera_to_world.shape == (4, 4) and frame.camera_to_world.dtype == np.float64
    assert frame.intrinsics.shape == (3, 3) and frame.intrinsics[2, 2] == 1
    assert (frame.width, frame.height) == (320, 240)
    assert pathlib.Path(frame.image_path).is_file()
    assert frame.depth_path is None or pathlib.Path(frame.depth_path).is_file()


def test_load_dataset_reads_the_shared_redkitchen():
    folder = pathlib.Path(os.environ.get("FFLOC_SHARED_DIR", "")) / "data" / "7scenes_redkitchen"
    if not folder.is_dir():
        pytest.skip(f"{folder} not found")
    scene = ffloc.load_dataset(folder, format="7scenes")
    assert len(scene.mapping_indices()) == 150 and len(scene.query_indices()) == 100
    assert scene.metric
    assert all(frame.depth_path for frame in scene.frames[:3])


def test_load_dataset_refuses_a_missing_folder_naming_it(tmp_path):
    missing = tmp_path / "no-such-dataset"
    with pytest.raises(ffloc.Error, match="no-such-dataset"):
        ffloc.load_dataset(missing)
    with pytest.raises(ValueError):  # ffloc.Error is a ValueError
        ffloc.load_dataset(missing)
    with pytest.raises(ffloc.Error, match="format"):
        ffloc.load_dataset(missing, format="no-such-format")


# Maps

def test_build_map_writes_the_map_the_cli_writes(scene_dir, cli_map, tmp_path):
    built = ffloc.build_map(str(scene_dir), out=str(tmp_path / "py.ffmap"), method="classical", threads=1)
    cli = ffloc.Map.load(str(cli_map))
    assert built.method == cli.method == "classical"
    assert built.names == cli.names
    np.testing.assert_array_equal(built.camera_to_world, cli.camera_to_world)
    np.testing.assert_array_equal(built.points(), cli.points())
    assert built.build_report["added"] == len(cli)
    # Every mapping frame of the synthetic scene has depth: every point is lifted from it.
    assert built.build_report["points_from_depth"] == built.build_report["points"] > 0
    assert built.build_report["featureless_images"] == [] and built.build_report["skipped_featureless"] == 0
    assert built.build_report["every_frame"] is False  # the scene has its split
    triangulated = ffloc.build_map(str(scene_dir), out=str(tmp_path / "nd.ffmap"), use_depth=False, threads=1)
    assert triangulated.build_report["points_from_depth"] == 0 < triangulated.build_report["points"]
    assert built.points(100).shape[1] == 3 and len(built.points(100)) <= 100


def test_build_map_takes_a_scene_and_refuses_bad_options(scene_dir, tmp_path):
    scene = ffloc.load_dataset(scene_dir)
    with pytest.raises(ffloc.Error, match="method"):
        ffloc.build_map(scene, out=str(tmp_path / "m.ffmap"), method="no-such-method")
    with pytest.raises(ffloc.Error, match="no-such.ffmap"):
        ffloc.Map.load(str(tmp_path / "no-such.ffmap"))
    # Options the build would ignore are refused, as 'ffloc map' refuses their flags; they were
    # silently dropped.
    out = str(tmp_path / "ignored.ffmap")
    for options, message in (({"dtype": "bf16"}, "dtype: the classical method uses no network"),
                             ({"vlad": True}, "vlad: a classical map always holds its VLAD descriptors"),
                             ({"method": "fastforward", "max_features": 100},
                              "max_features: applies to the classical method only"),
                             ({"max_features": 10**9}, "max_features: must be in \\[1, 16777216\\]"),
                             ({"max_features": "many"}, "max_features: expected an integer")):
        with pytest.raises(ffloc.Error, match=message):
            ffloc.build_map(scene, out=out, **options)
    assert not pathlib.Path(out).exists()


# Localization

def test_the_same_query_through_python_and_the_cli_gives_identical_poses(cli_map, query, cli_answer):
    localizer = ffloc.Localizer(ffloc.Map.load(str(cli_map)), threads=1)
    result = localizer.localize(query.image_path, query.intrinsics)
    assert result.status == cli_answer["status"] != "failed"
    np.testing.assert_array_equal(result.pose, np.array(cli_answer["camera_to_world"]))
    np.testing.assert_array_equal(result.quaternion, cli_answer["world_to_camera"]["qwxyz"])
    np.testing.assert_array_equal(result.translation, cli_answer["world_to_camera"]["t"])
    assert without_timings(result.to_dict()) == without_timings(cli_answer)
    assert result.inliers == cli_answer["inliers"]
    assert set(result.timings) >= {"features", "pnp", "total"}
    assert result.evidence == cli_answer["evidence"] and "inlier_spread" in result.evidence


def test_the_correspondences_are_the_pairs_the_pose_was_estimated_from(cli_map, query):
    localizer = ffloc.Localizer(str(cli_map), threads=1)
    result = localizer.localize(query.image_path, query.intrinsics)
    pairs = result.correspondences
    n = len(pairs["pixels"])
    assert pairs["pixels"].shape == (n, 2) and pairs["points"].shape == (n, 3) and pairs["confidences"].shape == (n,)
    assert pairs["inliers"].dtype == bool and pairs["inliers"].shape == (n,)
    # The query has fewer pairs than PnP draws, so the mask holds exactly PnP's inliers.
    assert 0 < result.inliers == pairs["inliers"].sum() < n <= 5000
    # Each inlier's point, projected with the pose and the camera, lands within 8 px of its pixel.
    world_to_camera = np.linalg.inv(result.pose)
    in_camera = pairs["points"] @ world_to_camera[:3, :3].T + world_to_camera[:3, 3]
    projected = in_camera @ pairs["camera"].T
    error = np.linalg.norm(projected[:, :2] / projected[:, 2:] - pairs["pixels"], axis=1)
    assert np.all(error[pairs["inliers"]] < 8) and np.all(error[~pairs["inliers"]] >= 8)
    # A pose estimated again from them is the same pose, to a millimetre.
    again, _, _ = ffloc.estimate_absolute_pose(pairs["pixels"], pairs["points"], pairs["camera"],
                                               image_size=(query.width, query.height))
    assert np.linalg.norm(again[:3, 3] - result.pose[:3, 3]) < 1e-3
    # Without a pose no pair is an inlier.
    noise = np.random.default_rng(0).integers(0, 256, (query.height, query.width, 3), dtype=np.uint8)
    failed = localizer.localize(noise, query.intrinsics)
    assert failed.pose is None and not failed.correspondences["inliers"].any()


def test_an_array_and_four_numbers_give_the_pose_of_the_path_and_matrix(cli_map, query, cli_answer):
    localizer = ffloc.Localizer(str(cli_map), threads=1)
    image = ffloc.read_image(query.image_path)
    assert image.dtype == np.uint8 and image.shape == (query.height, query.width, 3)
    k = query.intrinsics
    result = localizer.localize(image, (k[0, 0], k[1, 1], k[0, 2], k[1, 2]), name=query.image_path)
    np.testing.assert_array_equal(result.pose, np.array(cli_answer["camera_to_world"]))
    # A crop's view (rows strided) is read in place, and so is a read-only array.
    padded = np.zeros((query.height, query.width + 7, 3), np.uint8)
    padded[:, : query.width] = image
    view = padded[:, : query.width]
    view.flags.writeable = False
    again = localizer.localize(view, k, name=query.image_path)
    np.testing.assert_array_equal(again.pose, result.pose)


def test_query_options_are_the_cli_flags(cli_map, query):
    k = query.intrinsics
    intrinsics = (k[0, 0], k[1, 1], k[0, 2], k[1, 2])
    cli = localize_with_cli(cli_map, query, "--top-k", 3, "--seed", 7)
    result = ffloc.Localizer(str(cli_map), top_k=3, seed=7, threads=1).localize(query.image_path, intrinsics)
    assert without_timings(result.to_dict()) == without_timings(cli)
    # The opposite view, which one retrieved image leaves uncertain: the second look adds an image.
    scene = ffloc.load_dataset(str(pathlib.Path(query.image_path).parents[1]))
    opposite = scene.frames[scene.query_indices()[2]]
    k = opposite.intrinsics
    opposite_intrinsics = (k[0, 0], k[1, 1], k[0, 2], k[1, 2])
    for pose_guided, flags, images in ((True, (), 2), (False, ("--no-pose-guided",), 1)):
        cli = localize_with_cli(cli_map, opposite, "--top-k", 1, *flags)
        result = ffloc.Localizer(str(cli_map), top_k=1, pose_guided=pose_guided, threads=1).localize(
            opposite.image_path, opposite_intrinsics)
        assert without_timings(result.to_dict()) == without_timings(cli)
        assert len(cli["selected"]) == images
    with pytest.raises(ffloc.Error, match="top_k"):
        ffloc.Localizer(str(cli_map), top_k=0)
    with pytest.raises(ffloc.Error, match="no_such_option"):
        ffloc.Localizer(str(cli_map), no_such_option=1)
    # Values of the wrong type name the option (pybind11's own cast named nothing, and took 1.5).
    for options, message in (({"top_k": 1.5}, "top_k: expected an integer, got 1.5"),
                             ({"top_k": "3"}, "top_k: expected an integer, got '3'"),
                             ({"seed": -1}, "seed: expected a non-negative integer within range, got -1"),
                             # The CLI's and the server's range (2**63 was taken here alone).
                             ({"seed": 2**63}, r"seed: expected an integer in \[0, 9223372036854775807\], got 9223372036854775808"),
                             ({"verify": "no"}, "verify: expected True or False, got 'no'")):
        with pytest.raises(ffloc.Error, match=message):
            ffloc.Localizer(str(cli_map), **options)
    ffloc.Localizer(str(cli_map), top_k=np.int64(3))  # a NumPy integer is an integer


@pytest.mark.parametrize(
    "image, message",
    [
        (np.zeros((240, 320, 3), np.float32), "image: dtype must be uint8, got float32"),
        (np.zeros((240, 320), np.uint8), r"image: shape must be H x W x 3 \(RGB\), got \(240, 320\)"),
        (np.zeros((240, 320, 4), np.uint8), "got \\(240, 320, 4\\)"),
        ("/no/such/image.png", "/no/such/image.png"),
        (42, "image: expected a path"),
        # A file's encoded bytes were taken as a path (a 77,000-character error).
        (b"\xff\xd8\xff\xe0\x00\x10JFIF" + bytes(5000), "image: got 5010 bytes that are no path \\(an encoded image\\?\\)"),
        # Refused as a file of its size is, before a 4.8 GB copy (a view costs nothing to make).
        (np.broadcast_to(np.zeros((1, 1, 3), np.uint8), (40000, 40000, 3)),
         r"image: shape \(40000, 40000, 3\) is more than the 1073741824 pixels an image file may decode to"),
    ],
)
def test_bad_images_raise_errors_naming_the_image(cli_map, query, image, message):
    localizer = ffloc.Localizer(str(cli_map))
    with pytest.raises(ffloc.Error, match=message):
        localizer.localize(image, query.intrinsics)


def test_a_name_of_another_type_is_refused_naming_it(cli_map, query):
    # It was pybind11's TypeError, whose message printed the whole image array.
    localizer = ffloc.Localizer(str(cli_map), threads=1)
    with pytest.raises(ffloc.Error, match="name: expected a string, got 5"):
        localizer.localize(query.image_path, query.intrinsics, name=5)
    assert localizer.localize(query.image_path, query.intrinsics, name=None).to_dict()["name"] == str(query.image_path)


@pytest.mark.parametrize(
    "intrinsics, message",
    [
        (np.eye(4), "intrinsics: expected a 3x3 matrix or \\(fx, fy, cx, cy\\), got shape \\(4, 4\\)"),
        ((100.0, 100.0, 80.0), "got shape \\(3,\\)"),
        (np.array([[100, 1, 80], [0, 100, 60], [0, 0, 1]]), "intrinsics: a 3x3 matrix must be"),
        (("a", "b", "c", "d"), "intrinsics: expected numbers"),
        ((-100.0, 100.0, 80.0, 60.0), "fx"),
        ((100.0, 100.0, 500.0, 60.0), "cx"),
    ],
)
def test_bad_intrinsics_raise_errors_naming_the_field(cli_map, query, intrinsics, message):
    localizer = ffloc.Localizer(str(cli_map))
    with pytest.raises(ffloc.Error, match=message):
        localizer.localize(query.image_path, intrinsics)


def test_distortion_must_have_an_opencv_length(cli_map, query):
    localizer = ffloc.Localizer(str(cli_map))
    with pytest.raises(ffloc.Error, match="distortion: expected 4, 5 or 8"):
        localizer.localize(query.image_path, query.intrinsics, distortion=[0.1, 0.2, 0.3])
    # Zero distortion undistorts to the same pixels.
    result = localizer.localize(query.image_path, query.intrinsics, distortion=[0, 0, 0, 0])
    assert result.status in ("localized", "uncertain", "failed")


def test_the_gil_is_released_while_a_map_is_built(scene_dir, tmp_path):
    ticks = []
    done = threading.Event()

    def tick():
        while not done.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.005)

    ticker = threading.Thread(target=tick)
    ticker.start()
    start = time.monotonic()
    ffloc.build_map(scene_dir, out=str(tmp_path / "gil.ffmap"), threads=1)
    end = time.monotonic()
    done.set()
    ticker.join()
    during = [t for t in ticks if start < t < end]
    # Held by the call, the GIL would keep the ticker from running at all until the call returns;
    # a loose bound, as a loaded machine may give the ticker few turns.
    assert len(during) >= 5, f"{len(during)} ticks during a {end - start:.2f} s call"


def test_queries_from_several_threads_give_the_poses_of_serial_queries(cli, scene_dir, cli_map, query, tmp_path):
    """Python threads that localize at once, with one localizer and with others at other thread
    counts, beside image reads: the library's thread pools are the process's, and resizing
    OpenCV's under another thread's loop crashed the interpreter or hung it."""
    ff_map = tmp_path / "threads_ff.ffmap"
    cli("map", "--dataset", scene_dir, "-o", ff_map, "--method", "fastforward", "--threads", 2, "--quiet")
    shared = ffloc.Localizer(str(ff_map), threads=2)
    others = [ffloc.Localizer(str(ff_map), threads=1), ffloc.Localizer(str(cli_map), threads=1)]
    image = ffloc.read_image(query.image_path)

    def pose(localizer):
        result = localizer.localize(image, query.intrinsics)
        return None if result.pose is None else result.pose.tobytes()

    expected = {id(localizer): pose(localizer) for localizer in [shared, *others]}
    mismatches, errors = [], []

    def work(localizer, rounds):
        try:
            for _ in range(rounds):
                if pose(localizer) != expected[id(localizer)]:
                    mismatches.append(id(localizer))
                ffloc.read_image(query.image_path)
        except Exception as error:  # noqa: BLE001 - reported by the assertion below
            errors.append(repr(error))

    workers = [threading.Thread(target=work, args=(localizer, 25)) for localizer in [shared, shared, shared, *others]]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    assert errors == []
    assert mismatches == []
    with pytest.raises(ffloc.Error, match="threads: must be 0"):
        ffloc.Localizer(shared.map, threads=999)
    # Another type was pybind11's TypeError, naming no argument (an outside probe).
    with pytest.raises(ffloc.Error, match="threads: expected an integer, got 1.5"):
        ffloc.Localizer(shared.map, threads=1.5)
    with pytest.raises(ffloc.Error, match="threads: expected an integer, got '2'"):
        ffloc.evaluate("unused", threads="2")


def test_paths_whose_bytes_are_not_utf8_work_as_python_gives_them(scene_dir, query, tmp_path):
    """A folder named in Latin-1 bytes, as an old camera's card or a Windows share gives it:
    Python decodes such names with surrogates (os.fsdecode), which a cast to UTF-8 refused."""
    folder = os.path.join(os.fsencode(str(tmp_path)), b"caf\xe9")
    shutil.copytree(os.fsencode(str(scene_dir)), folder)
    scene = ffloc.load_dataset(os.fsdecode(folder))
    assert os.fsencode(scene.root) == folder
    assert all(os.path.exists(frame.image_path) for frame in scene.frames)
    out = os.path.join(folder, b"m\xe4p.ffmap")
    built = ffloc.build_map(scene, out=out, threads=1)
    assert os.fsencode(built.path) == out and built.names == ffloc.Map.load(os.fsdecode(out)).names
    image = next(frame.image_path for frame in scene.frames if frame.name == query.name)
    result = ffloc.Localizer(built).localize(image, query.intrinsics)
    assert result.pose is not None
    with pytest.raises(ffloc.Error, match=r"caf\\xe9"):  # the bytes shown as escapes in the message
        ffloc.read_image(os.path.join(folder, b"missing.png"))
    # A uint8 array is uint8 whatever its byte order says: only the dtype's identity differed.
    # Shown with escapes where people read them, and named as Python names the file in the answer.
    assert "caf\\xe9" in repr(built)
    assert os.fsencode(result.to_dict()["name"]) == os.fsencode(image)
    assert set(result.selected) <= set(built.names)
    pixels = ffloc.read_image(query.image_path)
    marked = ffloc.Localizer(built).localize(pixels.view(np.dtype("u1").newbyteorder(">")), query.intrinsics)
    assert np.array_equal(marked.pose, ffloc.Localizer(built).localize(pixels, query.intrinsics).pose)


# The solver

def synthetic_pairs(count, outliers, seed=1):
    rng = np.random.default_rng(seed)
    k = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    angle = 0.3
    rotation = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
    camera_to_world = np.eye(4)
    camera_to_world[:3, :3] = rotation
    camera_to_world[:3, 3] = [0.5, -0.2, 0.1]
    in_camera = np.column_stack([rng.uniform(-2, 2, count), rng.uniform(-1.5, 1.5, count), rng.uniform(2, 6, count)])
    points3d = in_camera @ rotation.T + camera_to_world[:3, 3]
    points2d = (in_camera[:, :2] / in_camera[:, 2:]) * [500, 500] + [320, 240]
    wrong = rng.choice(count, outliers, replace=False)
    points2d[wrong] = rng.uniform(0, 640, (outliers, 2))
    return points2d, points3d, k, camera_to_world, wrong


def test_estimate_absolute_pose_recovers_the_pose_and_flags_outliers():
    points2d, points3d, k, truth, wrong = synthetic_pairs(400, 100)
    pose, inliers, info = ffloc.estimate_absolute_pose(points2d, points3d, k, {"seed": 3}, image_size=(640, 480))
    assert info["success"] and info["status"] == "success"
    np.testing.assert_allclose(pose, truth, atol=1e-6)
    assert inliers.dtype == np.bool_ and inliers.shape == (400,)
    assert not inliers[wrong].any()
    assert inliers.sum() == info["inliers"] == 300
    # The same seed, the same answer; the solvers of the CLI's --solver are both there.
    again, _, _ = ffloc.estimate_absolute_pose(points2d, points3d, k, {"seed": 3})
    np.testing.assert_array_equal(pose, again)
    usac, _, info = ffloc.estimate_absolute_pose(points2d, points3d, (500, 500, 320, 240), {"solver": "opencv-usac"})
    np.testing.assert_allclose(usac, truth, atol=1e-6)


def test_estimate_absolute_pose_fails_as_a_status_on_noise():
    rng = np.random.default_rng(2)
    pose, inliers, info = ffloc.estimate_absolute_pose(rng.uniform(0, 640, (200, 2)), rng.uniform(-1, 1, (200, 3)),
                                                       (500, 500, 320, 240))
    assert pose is None and not info["success"] and not inliers.any()


@pytest.mark.parametrize(
    "points2d, points3d, options, message",
    [
        (np.zeros((10, 3)), np.zeros((10, 3)), None, "points2d: expected an N x 2 array, got shape \\(10, 3\\)"),
        (np.zeros((10, 2)), np.zeros((9, 3)), None, "points3d: 9 points for 10 pixels"),
        (np.zeros((10, 2)), np.zeros(30), None, "points3d: expected an N x 3 array, got shape \\(30,\\)"),
        (np.zeros((10, 2)), np.zeros((10, 3)), {"no_such_key": 1}, "options: unknown key 'no_such_key'"),
        (np.zeros((10, 2)), np.zeros((10, 3)), {"solver": "magic"}, "magic"),
        (np.zeros((10, 2)), np.zeros((10, 3)), {"inlier_threshold_px": -1.0}, "pnp.inlier_threshold_px"),
        (np.zeros((10, 2)), np.zeros((10, 3)), {"seed": 1}, "image_size: must be positive, got 0x480"),
        (np.zeros((10, 2)), np.zeros((10, 3)), {"max_iterations": 1.5}, "max_iterations: expected an integer, got 1.5"),
        (np.zeros((10, 2)), np.zeros((10, 3)), {"refine": "yes"}, "refine: expected True or False, got 'yes'"),
        (np.zeros((10, 2)), np.zeros((10, 3)), {"min_inliers": -1}, "pnp.min_inliers: must not be negative, got -1"),
        (np.zeros((10, 2)), np.zeros((10, 3)), {"inlier_threshold_px": 2j}, "inlier_threshold_px: expected a number"),
        (np.zeros((10, 2), bool), np.zeros((10, 3)), None, "points2d: expected numbers, got an array of bool"),
    ],
)
def test_estimate_absolute_pose_refuses_bad_input(points2d, points3d, options, message):
    size = (0, 480) if "image_size" in message else None
    with pytest.raises(ffloc.Error, match=message):
        ffloc.estimate_absolute_pose(points2d, points3d, (500, 500, 320, 240), options, image_size=size)


def test_estimate_absolute_pose_refuses_a_principal_point_no_image_has():
    # Without image_size the image is taken to span twice the principal point; cx = 1e12 made that
    # side overflow an int (undefined behaviour), reported as "image_size: ... -2147483648x481".
    with pytest.raises(ffloc.Error, match="intrinsics: cx = 1e\\+12 puts the image centre where no image is"):
        ffloc.estimate_absolute_pose(np.zeros((10, 2)), np.zeros((10, 3)), (500, 500, 1e12, 240))
    # At (0, 0), as for pixels measured from the centre, the image was 1 x 1 (an outside probe).
    with pytest.raises(ffloc.Error, match="intrinsics: cx = 0 puts the image centre where no image is"):
        ffloc.estimate_absolute_pose(np.zeros((10, 2)), np.zeros((10, 3)), (500, 500, 0, 0))
    # With image_size, a principal point outside that image: success, 5 m off, before.
    points2d, points3d, _, _, _ = synthetic_pairs(200, 0)
    with pytest.raises(ffloc.Error, match="cx, cy: the principal point \\(1000, 240\\) lies outside the 640x480 image"):
        ffloc.estimate_absolute_pose(points2d, points3d, (500, 500, 1000, 240), image_size=(640, 480))
    # Rows that are not finite were left out without a word.
    bad = points2d.copy()
    bad[17, 1] = np.nan
    with pytest.raises(ffloc.Error, match="points2d: row 17 holds a value that is not finite"):
        ffloc.estimate_absolute_pose(bad, points3d, (500, 500, 320, 240))
    # Without image_size, a focal length no camera has went on to RANSAC (1e300 px: "no model").
    with pytest.raises(ffloc.Error, match="fx: focal length 1e\\+300 px is not in .* pass image_size"):
        ffloc.estimate_absolute_pose(points2d, points3d, (1e300, 500, 320, 240))


def test_arguments_of_the_wrong_type_raise_errors_naming_them():
    with pytest.raises(ffloc.Error, match="options: expected a dict of PnP options, got str"):
        ffloc.estimate_absolute_pose(np.zeros((10, 2)), np.zeros((10, 3)), (500, 500, 320, 240), "notadict")
    with pytest.raises(ffloc.Error, match="map: expected an ffloc.Map or a map file path, got NoneType"):
        ffloc.Localizer(None)


def test_no_class_can_be_made_empty(cli_map, query):
    # X.__new__(X) gave an object with no C++ object behind it: len() of a Map, Scene.mapping_indices()
    # and Frame.distortion crashed the interpreter, Localizer.localize read garbage settings.
    for kind, message in ((ffloc.Map, "ffloc.Map.load\\(path\\) opens one"),
                          (ffloc.Result, "Localizer.localize returns one"),
                          (ffloc.Scene, "ffloc.load_dataset\\(path\\) reads one"),
                          (ffloc.Frame, "Scene.frames holds"),
                          (ffloc.Localizer, "ffloc.Localizer\\(map\\) makes one")):
        with pytest.raises(TypeError, match=f"ffloc.{kind.__name__} cannot be made empty: {message}"):
            kind.__new__(kind)
    with pytest.raises(TypeError, match="ffloc.Map cannot be made empty"):
        ffloc.Map.__new__(ffloc.Map, str(cli_map))
    # What the library and the constructor make still comes through.
    opened = ffloc.Map.load(cli_map)
    localizer = ffloc.Localizer(opened, threads=1)
    assert len(opened) == len(localizer.map) > 0
    assert localizer.localize(query.image_path, query.intrinsics).status != "failed"
    assert query.name and query.split == "query"  # a Frame of Scene.frames


def test_a_model_named_beside_an_opened_map_is_refused_not_ignored(cli_map):
    opened = ffloc.Map.load(cli_map)  # os.PathLike taken, as every path argument, and bytes
    assert ffloc.Map.load(os.fsencode(str(cli_map))).method == opened.method == "classical"
    with pytest.raises(ffloc.Error, match="model: a Map is opened with its model; pass it to ffloc.Map.load"):
        ffloc.Localizer(opened, model="/nonexistent.safetensors")
    with pytest.raises(ffloc.Error, match="dtype: a Map is opened with its model"):
        ffloc.Localizer(opened, dtype="bf16")
    # A classical map has no model: one named when it is loaded was ignored.
    for setting in ({"dtype": "f16"}, {"model": "default"}):
        with pytest.raises(ffloc.Error, match=f"{next(iter(setting))}: the map is a classical map, which does not use it"):
            ffloc.Map.load(cli_map, **setting)


def test_ctrl_c_stops_a_build_before_it_replaces_the_map(cli, tmp_path):
    # Heard only when the call returned before, its new map written over the old one.
    cli("synth", "--out", tmp_path / "synth", "--seed", 11, "--kind", "indoor", "--quiet")
    scene = str(tmp_path / "synth" / "scene_000_indoor")
    out = tmp_path / "m.ffmap"
    started = time.monotonic()
    ffloc.build_map(scene, out=str(out), threads=1)
    whole = time.monotonic() - started
    before = out.read_bytes()

    def interrupt(*_):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGALRM, interrupt)
    try:
        signal.setitimer(signal.ITIMER_REAL, whole / 4)
        started = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            ffloc.build_map(scene, out=str(out), threads=1, max_features=3000)
        assert time.monotonic() - started < whole * 0.75
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert out.read_bytes() == before


def test_ctrl_c_ends_a_wait_for_another_writers_lock(cli, tmp_path):
    # The wait blocked in flock, deaf to Ctrl-C until the other writer let go.
    cli("synth", "--out", tmp_path / "synth", "--seed", 11, "--kind", "indoor", "--quiet")
    scene = str(tmp_path / "synth" / "scene_000_indoor")
    out = tmp_path / "m.ffmap"
    held = open(tmp_path / ".m.ffmap.lock", "w")
    fcntl.flock(held, fcntl.LOCK_EX)
    release = threading.Timer(5.0, lambda: fcntl.flock(held, fcntl.LOCK_UN))
    release.start()

    def interrupt(*_):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGALRM, interrupt)
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.5)
        started = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            ffloc.build_map(scene, out=str(out), threads=1)
        assert time.monotonic() - started < 3.0  # not when the other writer let go, at 5 s
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        release.cancel()
        held.close()
    assert not out.exists()


def test_settings_the_maps_method_ignores_and_empty_paths_are_refused(cli_map, scene_dir):
    # A classical map took FastForward's settings silently, where the CLI refuses their flags.
    for setting in (dict(features=10), dict(selection="random"), dict(retrieval="vlad"), dict(verify=False)):
        with pytest.raises(ffloc.Error, match=list(setting)[0] + ": the map is a classical map, which does not use it"):
            ffloc.Localizer(ffloc.Map.load(str(cli_map)), **setting)
    with pytest.raises(ffloc.Error, match="model: the map is a classical map, which does not use it"):
        ffloc.Localizer(str(cli_map), model="random:tiny")
    # build_map(out="") built the whole map, then failed to rename it into place.
    with pytest.raises(ffloc.Error, match="out: the path is empty"):
        ffloc.build_map(str(scene_dir), out="")
    # A max_points near 2**64 wrapped the sampling stride to 0: SIGFPE.
    assert ffloc.Map.load(str(cli_map)).points(2**64 - 1).shape[1] == 3
    # Counts below 0 raised pybind11's TypeError with its signatures (an outside probe).
    with pytest.raises(ffloc.Error, match="max_points: expected a non-negative integer within range, got -1"):
        ffloc.Map.load(str(cli_map)).points(-1)
    with pytest.raises(ffloc.Error, match="max_queries: expected a non-negative integer within range, got -1"):
        ffloc.evaluate(str(scene_dir), max_queries=-1)


# Evaluation

def test_evaluate_gives_the_summary_the_cli_writes(scene_dir, cli, tmp_path):
    summary_path = tmp_path / "eval.json"
    cli("eval", "--dataset", scene_dir, "--methods", "oracle-depth,classical", "--json", summary_path, "--quiet",
        "--threads", 1)
    from_cli = json.loads(summary_path.read_text())
    from_python = ffloc.evaluate(str(scene_dir), methods=["oracle-depth", "classical"], threads=1)
    assert set(from_python) == set(from_cli) == {"results"}
    assert len(from_python["results"]) == 2
    for ours, theirs in zip(from_python["results"], from_cli["results"]):
        assert set(ours) == set(theirs)
        assert ours["metric"] is True  # a synthetic scene is in metres
        # Latency is measured, so it differs from run to run; everything else is equal.
        ours.pop("latency_ms")
        theirs.pop("latency_ms")
        assert ours == theirs


def test_evaluate_takes_one_method_by_its_name(scene_dir):
    one = ffloc.evaluate(scene_dir, methods="oracle-depth", threads=1)
    listed = ffloc.evaluate(scene_dir, methods=("oracle-depth",), threads=1)
    assert [result["method"] for result in one["results"]] == ["oracle-depth"]
    for result in (one, listed):
        result["results"][0].pop("latency_ms")
    assert one == listed


def test_evaluate_refuses_unknown_methods(scene_dir):
    with pytest.raises(ffloc.Error, match="methods: unknown method 'magic'"):
        ffloc.evaluate(scene_dir, methods=["magic"])
    with pytest.raises(ffloc.Error, match="methods: names no method"):
        ffloc.evaluate(scene_dir, methods=[])
    # Run twice without a word before, as the CLI's --methods had been.
    with pytest.raises(ffloc.Error, match="methods: 'classical' is given twice"):
        ffloc.evaluate(scene_dir, methods=["classical", "classical"])
    with pytest.raises(ffloc.Error, match="dataset: expected a folder path"):
        ffloc.evaluate(3.5)
    with pytest.raises(ffloc.Error, match="methods: expected a method name or a list of them, got 3"):
        ffloc.evaluate(scene_dir, methods=3)
    with pytest.raises(ffloc.Error, match="methods: expected a string, got None"):
        ffloc.evaluate(scene_dir, methods=["classical", None])
    # A setting of a method not evaluated ran as if it were not given.
    with pytest.raises(ffloc.Error, match=r"features: none of the methods evaluated \(classical, oracle-depth\) uses it"):
        ffloc.evaluate(scene_dir, methods=["classical", "oracle-depth"], features=500)
    with pytest.raises(ffloc.Error, match=r"pose_guided: none of the methods evaluated \(fastforward\) uses it"):
        ffloc.evaluate(scene_dir, methods=["fastforward"], pose_guided=False)
    # As the CLI refuses --no-depth, --model and --dtype (an outside probe: use_depth=False passed).
    with pytest.raises(ffloc.Error, match="use_depth: only classical uses it, and methods does not run it"):
        ffloc.evaluate(scene_dir, methods="sift-baseline", use_depth=False)
    with pytest.raises(ffloc.Error, match=r"model: none of the methods evaluated \(classical\) uses it"):
        ffloc.evaluate(scene_dir, methods="classical", model="default")
    with pytest.raises(ffloc.Error, match=r"dtype: none of the methods evaluated \(oracle-depth\) uses it"):
        ffloc.evaluate(scene_dir, methods="oracle-depth", dtype="bf16")


def test_evaluate_of_an_empty_mapping_split_says_so(cli, tmp_path):
    # It blamed SIFT ("fewer than two keypoints"), where the CLI names the split.
    cli("synth", "--out", tmp_path / "synth", "--seed", 11, "--kind", "indoor", "--size", "160x120",
        "--mapping-frames", 3, "--query-frames", 1, "--quiet")
    scene = tmp_path / "synth" / "scene_000_indoor"
    (scene / "split_query.txt").write_text("images/query_0000_near.png\n")
    with pytest.raises(ffloc.Error, match="split 'mapping' is empty \\(split_query.txt lists 1 frame"):
        ffloc.evaluate(str(scene), methods="classical", threads=1)
    # And a map of it, as the CLI's `ffloc map` builds it (it said "dataset has no mapping frames").
    with pytest.raises(ffloc.Error, match="split 'mapping' is empty \\(split_query.txt lists 1 frame"):
        ffloc.build_map(str(scene), out=str(tmp_path / "m.ffmap"), threads=1)
