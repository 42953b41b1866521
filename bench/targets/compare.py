"""pingcal vs OpenCV on the same images: images per second, and centre accuracy where the
truth is known (a rendered 24-megapixel image of ellipses with known centres).

OpenCV pipeline: SimpleBlobDetector (bright blobs, its default multi-threshold search) finds
the targets; each is refined by fitEllipse on the outer contour of an Otsu-thresholded patch
around it (the usual way to get sub-pixel centres with OpenCV). Both sides run with the same
thread count (cv2.setNumThreads; RAYON_NUM_THREADS for pingcal), 1 and 2 by default.

Timing: the two programs are run alternately, `--reps` times each, and the best (shortest)
time of each is reported, so that load from other jobs on the machine hits both alike.
"""
import argparse, glob, json, multiprocessing, os, resource, subprocess, time
import numpy as np
import cv2



def render_synthetic(path_png, path_truth, seed=1):
    """6000x4000 px, ~2400 ellipses (major axis 8-40 px, tilt up to 70 deg), 4x4 supersampling,
    Gaussian blur sigma 1 px, noise sigma 2 grey levels, contrast 150 on a background of 30."""
    rng = np.random.default_rng(seed)
    W, H = 6000, 4000
    img = np.full((H, W), 30.0, np.float32)
    truth = []
    step = 100
    for gy in range(step // 2, H - step // 2, step):
        for gx in range(step // 2, W - step // 2, step):
            a = rng.uniform(4, 20)
            b = a * np.cos(np.radians(rng.uniform(0, 70)))
            th = rng.uniform(0, np.pi)
            cx, cy = gx + rng.uniform(-5, 5), gy + rng.uniform(-5, 5)
            r = int(np.ceil(a)) + 2
            x0, y0 = int(cx) - r, int(cy) - r
            n = 2 * r + 1
            ss = 4
            o = (np.arange(n * ss) + 0.5) / ss - 0.5
            X, Y = np.meshgrid(x0 + o, y0 + o)
            dx, dy = X - cx, Y - cy
            u = (np.cos(th) * dx + np.sin(th) * dy) / a
            v = (-np.sin(th) * dx + np.cos(th) * dy) / b
            inside = (u * u + v * v <= 1.0).astype(np.float32)
            cov = inside.reshape(n, ss, n, ss).mean(axis=(1, 3))
            img[y0:y0 + n, x0:x0 + n] += 150.0 * cov
            truth.append((cx, cy))
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    img += rng.normal(0, 2.0, img.shape).astype(np.float32)
    cv2.imwrite(path_png, np.clip(img + 0.5, 0, 255).astype(np.uint8))
    np.savetxt(path_truth, np.array(truth))


def opencv_detect(path):
    img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    p = cv2.SimpleBlobDetector_Params()
    p.filterByColor = True
    p.blobColor = 255
    p.filterByArea = True
    p.minArea = 15
    p.maxArea = 40000
    p.filterByCircularity = False
    p.filterByInertia = True
    p.minInertiaRatio = 0.25
    p.filterByConvexity = True
    p.minConvexity = 0.85
    kps = cv2.SimpleBlobDetector_create(p).detect(img)
    centres = []
    for k in kps:
        x, y = k.pt
        r = int(k.size) + 4
        x0, y0 = max(int(x) - r, 0), max(int(y) - r, 0)
        patch = img[y0:int(y) + r + 1, x0:int(x) + r + 1]
        if patch.size == 0:
            continue
        _, th = cv2.threshold(patch, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        cs, _ = cv2.findContours(th, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        best = None
        for c in cs:
            if len(c) < 5:
                continue
            (ex, ey), _, _ = cv2.fitEllipse(c)
            d = (ex + x0 - x) ** 2 + (ey + y0 - y) ** 2
            if best is None or d < best[0]:
                best = (d, ex + x0, ey + y0)
        if best is not None:
            centres.append((best[1], best[2]))
        else:
            centres.append((x, y))
    return centres


def accuracy(found, truth, gate=2.0):
    found = np.asarray(found).reshape(-1, 2)
    errs = []
    for t in truth:
        if len(found) == 0:
            break
        d = np.hypot(found[:, 0] - t[0], found[:, 1] - t[1])
        i = int(np.argmin(d))
        if d[i] < gate:
            errs.append(found[i] - t)
    errs = np.asarray(errs)
    if len(errs) == 0:
        return 0, float("nan"), float("nan")
    return len(errs), float(np.sqrt((errs ** 2).sum(axis=1).mean())), float(np.abs(errs.mean(axis=0)).max())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--pingcal", required=True)
    ap.add_argument("--panel", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--pingcal-base", help="optional second build (e.g. an older commit), timed in the same runs")
    ap.add_argument("--threads", default="1,2", help="comma-separated thread counts")
    ap.add_argument("--reps", type=int, default=5, help="alternating runs of each side; best time kept")
    a = ap.parse_args()
    syn = os.path.join(a.work, "synthetic24mp.png")
    syn_truth = os.path.join(a.work, "synthetic24mp_truth.txt")
    if not os.path.exists(syn):
        render_synthetic(syn, syn_truth)
    truth = np.loadtxt(syn_truth)
    panel = sorted(glob.glob(os.path.join(a.panel, "*.tif")))
    base = " pingcal-base images/s | base speed-up | base CPU ms/image |" if a.pingcal_base else ""
    print("| image set | images | threads | pingcal images/s | OpenCV images/s | speed-up |"
          " pingcal CPU ms/image | OpenCV CPU ms/image |" + base)
    print("|---|---|---|---|---|---|---|---|" + ("---|---|---|" if a.pingcal_base else ""))
    rows = []
    for threads in [int(t) for t in a.threads.split(",")]:
        cv2.setNumThreads(threads)
        env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
        for name, files in [("real AICON panel (2000x1333)", panel), ("synthetic 24 MP (6000x4000)", [syn])]:
            if not files:
                print(f"| {name} | 0 (data absent) | | | | | | |")
                continue
            out = os.path.join(a.work, "pingcal.json")
            tp, to, tb = float("inf"), float("inf"), float("inf")
            cp, co, cb = float("inf"), float("inf"), float("inf")  # CPU seconds (user + sys)

            def child_cpu():
                r = resource.getrusage(resource.RUSAGE_CHILDREN)
                return r.ru_utime + r.ru_stime

            for _ in range(a.reps):
                if a.pingcal_base:
                    t0, c0 = time.perf_counter(), child_cpu()
                    subprocess.run([a.pingcal_base, out + ".base"] + files, check=True, env=env)
                    tb, cb = min(tb, time.perf_counter() - t0), min(cb, child_cpu() - c0)
                t0, c0 = time.perf_counter(), child_cpu()
                subprocess.run([a.pingcal, out] + files, check=True, env=env)
                tp, cp = min(tp, time.perf_counter() - t0), min(cp, child_cpu() - c0)
                t0, c0 = time.perf_counter(), time.process_time()
                oc = [opencv_detect(f) for f in files]
                to, co = min(to, time.perf_counter() - t0), min(co, time.process_time() - c0)
            res = json.load(open(out))
            print(f"| {name} | {len(files)} | {threads} | {len(files) / tp:.2f} | {len(files) / to:.2f} | {to / tp:.2f}x |"
                  f" {1e3 * cp / len(files):.1f} | {1e3 * co / len(files):.1f} |"
                  + (f" {len(files) / tb:.2f} | {to / tb:.2f}x | {1e3 * cb / len(files):.1f} |" if a.pingcal_base else ""), flush=True)
            rows.append((name, res, oc))
    print()
    print("Centre accuracy on the synthetic image (%d ellipses, truth known; matched within 2 px):" % len(truth))
    print()
    print("| method | matched | RMS error px | max mean bias px |")
    print("|---|---|---|---|")
    for name, res, oc in rows[-1:] if rows and rows[-1][0].startswith("synthetic") else []:
        for label, pts in [("pingcal ellipse fit", res[0]["centres"]), ("pingcal centroid", res[0]["centroids"]), ("OpenCV blob + fitEllipse", oc[0])]:
            n, rms, bias = accuracy(pts, truth)
            print(f"| {label} | {n} | {rms:.4f} | {bias:.4f} |")
    # OpenCV has no parallelism of its own here (SimpleBlobDetector and imread run on one thread
    # whatever setNumThreads says), but a batch of images can be spread over processes: time that
    # too, against pingcal's best time on the same batch with as many threads.
    pools = [int(t) for t in a.threads.split(",") if int(t) > 1]
    if pools and len(panel) > 1:
        print()
        print("OpenCV spread over processes (multiprocessing.Pool, one image per task, cv2.setNumThreads(1)):")
        print()
        print("| image set | processes | OpenCV images/s | pingcal images/s (same thread count) | speed-up |")
        print("|---|---|---|---|---|")
        for n in pools:
            env = dict(os.environ, RAYON_NUM_THREADS=str(n))
            out = os.path.join(a.work, "pingcal.json")
            tp, to = float("inf"), float("inf")
            # "spawn": workers forked from this process would inherit OpenCV's thread pool
            # mid-state and hang.
            ctx = multiprocessing.get_context("spawn")
            with ctx.Pool(n, initializer=cv2.setNumThreads, initargs=(1,)) as pool:
                pool.map(opencv_detect, panel[:n])  # start-up of the workers, not timed
                for _ in range(a.reps):
                    t0 = time.perf_counter()
                    subprocess.run([a.pingcal, out] + panel, check=True, env=env)
                    tp = min(tp, time.perf_counter() - t0)
                    t0 = time.perf_counter()
                    pool.map(opencv_detect, panel, chunksize=1)
                    to = min(to, time.perf_counter() - t0)
            print(f"| real AICON panel (2000x1333) | {n} | {len(panel) / to:.2f} | {len(panel) / tp:.2f} | {to / tp:.2f}x |", flush=True)
    print()
    print("(pingcal timings include process start and image loading; OpenCV's include cv2.imread."
          f" Best of {a.reps} alternating runs each.)")


if __name__ == "__main__":
    main()
