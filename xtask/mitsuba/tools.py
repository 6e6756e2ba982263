#!/usr/bin/env python3
"""Helpers for xtask/mitsuba/compare.sh (run with the peer's venv, which has
Mitsuba to read and write EXR, and numpy).

  tools.py average OUT_STEM A.exr B.exr ...   mean of equal-spp renders -> OUT_STEM.exr/.png
  tools.py blocks REF.exr TEST.exr            bias check on 8x8-block means
  tools.py summarize bench.jsonl              medians of interleaved timings
  tools.py pair A.exr B.exr [REF.exr]         mean radiance of two renders; with REF, each
                                              one's RMSE against it (equal error at equal spp)
  tools.py table bench.jsonl [SUMMARY.jsonl]  compare.sh bench's table: per scene the median
                                              s/spp of each renderer, their ratio and each
                                              one's RMSE against the scene's reference at
                                              that spp, mean over the rounds (seeds); one
                                              JSON line per scene (also into SUMMARY), then
                                              the markdown table
  tools.py noise REF.exr REF_SPP CHUNK.exr ...  error of the chunks' mean against what noise
                                              explains: each chunk (equal spp, independent
                                              seeds) gives every pixel's variance, hence the
                                              expected squared error of the mean and of a
                                              REF_SPP reference from the same estimator
"""
import json
import statistics
import sys

import numpy as np


def mitsuba():
    import mitsuba as mi
    if not mi.variant():
        mi.set_variant("scalar_rgb")
    return mi


def load(path):
    a = np.array(mitsuba().Bitmap(path), dtype=np.float64)
    return a[..., :3]


def average(out_stem, paths):
    mi = mitsuba()
    acc = sum(load(p) for p in paths) / len(paths)
    img = np.ascontiguousarray(acc, dtype=np.float32)
    bmp = mi.Bitmap(img, mi.Bitmap.PixelFormat.RGB)
    bmp.write(out_stem + ".exr")
    x = np.clip(acc, 0.0, 1.0)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    png = np.ascontiguousarray(np.round(x * 255.0).astype(np.uint8))
    mi.Bitmap(png, mi.Bitmap.PixelFormat.RGB).write(out_stem + ".png")
    print("averaged %d images into %s.exr" % (len(paths), out_stem))


def blocks(ref_path, test_path, b=8):
    """Means over b x b blocks average the noise away (by b), so a
    difference that stays well above the blocks' noise is bias."""
    ref, test = load(ref_path), load(test_path)
    h, w, _ = ref.shape
    r = ref[: h - h % b, : w - w % b].reshape(h // b, b, w // b, b, 3).mean(axis=(1, 3))
    t = test[: h - h % b, : w - w % b].reshape(h // b, b, w // b, b, 3).mean(axis=(1, 3))
    d = t - r
    print(json.dumps({
        "block": b,
        "mean_ref": [round(float(x), 5) for x in ref.reshape(-1, 3).mean(0)],
        "mean_test": [round(float(x), 5) for x in test.reshape(-1, 3).mean(0)],
        "mean_rel_diff": [round(float(x), 5) for x in
                          (test.reshape(-1, 3).mean(0) / ref.reshape(-1, 3).mean(0) - 1)],
        "block_rmse": round(float(np.sqrt(np.mean(d ** 2))), 5),
        "block_mean_diff": round(float(d.mean()), 6),
        "worst_blocks": [
            {"row": int(i // d.shape[1]), "col": int(i % d.shape[1]),
             "ref": [round(float(x), 4) for x in r.reshape(-1, 3)[i]],
             "test": [round(float(x), 4) for x in t.reshape(-1, 3)[i]]}
            for i in np.argsort(-np.abs(d).max(axis=2).ravel())[:5]],
    }))


def noise(ref_path, ref_spp, paths, b=32):
    """Squared error of the mean of equal-spp chunks against the reference,
    split into what the two images' noise explains and the excess, per
    b x b block. The chunks' spp comes from CHUNK_SPP in the environment
    (default 1024); the reference is taken to have the chunks' per-sample
    variance (the same estimator) at REF_SPP samples."""
    import os
    chunk_spp = int(os.environ.get("CHUNK_SPP", "1024"))
    ref = load(ref_path)
    ch = np.stack([load(p) for p in paths])
    k = len(paths)
    avg = ch.mean(0)
    pv = ch.var(0, ddof=1)
    ours = pv / k
    theirs = pv * chunk_spp / ref_spp
    err2 = (avg - ref) ** 2
    n = err2.size
    print(json.dumps({
        "chunks": k, "spp": k * chunk_spp,
        "rmse": round(float(np.sqrt(err2.mean())), 5),
        "noise_ours": round(float(np.sqrt(ours.mean())), 5),
        "noise_ref_predicted": round(float(np.sqrt(theirs.mean())), 5),
        "rmse_explained_by_noise": round(float(np.sqrt((ours + theirs).mean())), 5),
        "excess_mse": float((err2 - ours - theirs).sum() / n),
    }))
    h, w, _ = ref.shape
    ex = (err2 - ours - theirs).mean(axis=2)[: h - h % b, : w - w % b]
    m = ex.reshape(h // b, b, w // b, b).mean(axis=(1, 3))
    print("excess squared error per %dx%d block, x1e6:" % (b, b))
    print(np.array2string(m * 1e6, precision=0, max_line_width=200, suppress_small=True))


def summarize(path):
    rows = [json.loads(l) for l in open(path) if l.strip()]
    med = {}
    for who in ("lucent", "mitsuba"):
        vals = [r["render_s"] for r in rows if r["who"] == who]
        med[who] = statistics.median(vals)
        spp = rows[0]["spp"]
        print("%-8s median %.3f s for %d spp = %.4f s/spp over %d rounds: %s" % (
            who, med[who], spp, med[who] / spp, len(vals), ", ".join("%.3f" % v for v in vals)))
    print("Mitsuba / Lucent time ratio (above 1: Lucent faster): %.2f" % (med["mitsuba"] / med["lucent"]))
    print("loads: " + "; ".join("%s %s" % (r["who"], r["load"]) for r in rows))


def pair(a_path, b_path, ref_path=None):
    a, b = load(a_path), load(b_path)
    out = {"mean_a": [round(float(x), 5) for x in a.reshape(-1, 3).mean(0)],
           "mean_b": [round(float(x), 5) for x in b.reshape(-1, 3).mean(0)],
           "rmse_a_b": round(float(np.sqrt(np.mean((a - b) ** 2))), 5)}
    if ref_path:
        ref = load(ref_path)
        out["rmse_a_ref"] = round(float(np.sqrt(np.mean((a - ref) ** 2))), 5)
        out["rmse_b_ref"] = round(float(np.sqrt(np.mean((b - ref) ** 2))), 5)
    print(json.dumps(out))


def seeds_error(ref_path, folder, first, last):
    """Equal error measured apart from time: FOLDER holds lucent_S.exr and
    mitsuba_S.exr for S in FIRST..LAST (compare.sh error-seeds). Prints one
    JSON line: each renderer's mean and median MSE against the reference
    and mean RMSE, Mitsuba's mean MSE over Lucent's with a bootstrap 90 %
    interval (resampling seeds), the median of the per-seed ratios, how
    many seeds Lucent's error is the lower, and how far each renderer's
    mean image lies from the reference (its bias plus what noise is left)."""
    ref = load(ref_path)
    seeds = list(range(int(first), int(last) + 1))
    if not seeds:
        sys.exit("seeds_error: no seeds from %s to %s (FIRST must not exceed LAST)" % (first, last))
    mse, means = {}, {}
    for who in ("lucent", "mitsuba"):
        acc, errs = 0.0, []
        for s in seeds:
            a = load("%s/%s_%d.exr" % (folder, who, s))
            acc = acc + a
            errs.append(float(np.mean((a - ref) ** 2)))
        mse[who] = np.array(errs)
        means[who] = acc / len(seeds)
    ratio = float(mse["mitsuba"].mean() / mse["lucent"].mean())
    rng = np.random.default_rng(1)
    boot = []
    for _ in range(2000):
        i = rng.integers(0, len(seeds), len(seeds))
        boot.append(mse["mitsuba"][i].mean() / mse["lucent"][i].mean())
    lo, hi = np.percentile(boot, [5, 95])
    out = {"seeds": len(seeds), "first": seeds[0], "last": seeds[-1],
           "mitsuba_over_lucent_mse": round(ratio, 4),
           "bootstrap_90": [round(float(lo), 3), round(float(hi), 3)],
           "per_seed_ratio_median": round(float(np.median(mse["mitsuba"] / mse["lucent"])), 4),
           "lucent_lower": int((mse["lucent"] < mse["mitsuba"]).sum())}
    for who in ("lucent", "mitsuba"):
        out[who] = {"mean_mse": float("%.4g" % mse[who].mean()), "median_mse": float("%.4g" % np.median(mse[who])),
                    "mean_rmse": round(float(np.sqrt(mse[who]).mean()), 5),
                    "image_mean": [round(float(x), 5) for x in means[who].reshape(-1, 3).mean(0)],
                    "rmse_of_mean_image": round(rmse(means[who], ref), 5)}
    print(json.dumps(out))


def rmse(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)))


def table(path, summary_path=None):
    """Reads the round lines of compare.sh bench (scene, who, round, spp,
    render_s, exr, ref, load) and prints what each scene measured."""
    rows = [json.loads(l) for l in open(path) if l.strip()]
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    refs = {}
    out = []
    for scene in scenes:
        mine = [r for r in rows if r["scene"] == scene]
        ref_path = mine[0]["ref"]
        ref = refs.setdefault(ref_path, load(ref_path))
        s = {"scene": scene, "spp": mine[0]["spp"], "rounds": len({r["round"] for r in mine}), "ref": ref_path}
        whos = ["lucent", "mitsuba"] + (["baseline"] if any(r["who"] == "baseline" for r in mine) else [])
        for who in whos:
            rs = [r for r in mine if r["who"] == who]
            s_per_spp = [r["render_s"] / r["spp"] for r in rs]
            errs = [rmse(load(r["exr"]), ref) for r in rs]
            s[who + "_s_per_spp"] = round(statistics.median(s_per_spp), 5)
            s[who + "_s_per_spp_rounds"] = [round(x, 5) for x in s_per_spp]
            s[who + "_rmse_mean"] = round(statistics.mean(errs), 5)
            s[who + "_rmse_rounds"] = [round(x, 5) for x in errs]
            s[who + "_mean_radiance"] = [round(float(x), 5) for x in
                                         np.mean([load(r["exr"]).reshape(-1, 3).mean(0) for r in rs], axis=0)]
        s["ref_mean_radiance"] = [round(float(x), 5) for x in ref.reshape(-1, 3).mean(0)]
        # Per round, Mitsuba's time over Lucent's in the same round (above 1:
        # Lucent faster); the median of those shares each round's load.
        pairs = {}
        for r in mine:
            pairs.setdefault(r["round"], {})[r["who"]] = r["render_s"]

        def per_round(key, num, den):
            # num's time over den's in each round that timed both, and their median.
            ratios = [p[num] / p[den] for p in pairs.values() if num in p and den in p]
            s[key + "_median"] = round(statistics.median(ratios), 3)
            s[key + "_rounds"] = [round(x, 3) for x in ratios]

        per_round("ratio", "mitsuba", "lucent")
        # The same ratio at equal error: an unbiased render's MSE falls as
        # 1/spp, so Lucent reaches Mitsuba's RMSE with (RMSE_L / RMSE_M)^2 of
        # its samples. Above the plain ratio when Lucent is less noisy per
        # sample, below it when noisier.
        s["ratio_equal_error"] = round(s["ratio_median"] * (s["mitsuba_rmse_mean"] / s["lucent_rmse_mean"]) ** 2, 3)
        if "baseline" in whos:
            # The older build in the same rounds: Mitsuba's time over its,
            # and Lucent's over its (below 1: the change is faster).
            per_round("baseline_ratio", "mitsuba", "baseline")
            per_round("lucent_over_baseline", "lucent", "baseline")
        s["loads"] = [r["load"] for r in mine]
        out.append(s)
        print(json.dumps(s))
    if summary_path:
        with open(summary_path, "w") as f:
            for s in out:
                f.write(json.dumps(s) + "\n")
    print()
    print("| scene | spp | Lucent s/spp | Mitsuba s/spp | Mitsuba / Lucent time (per-round median) "
          "| Lucent RMSE | Mitsuba RMSE | the ratio at equal error | rounds (seeds) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for s in out:
        print("| %s | %d | %.4f | %.4f | %.2f | %.5f | %.5f | %.2f | %d |" % (
            s["scene"], s["spp"], s["lucent_s_per_spp"], s["mitsuba_s_per_spp"], s["ratio_median"],
            s["lucent_rmse_mean"], s["mitsuba_rmse_mean"], s["ratio_equal_error"], s["rounds"]))
    if any("baseline_ratio_median" in s for s in out):
        print()
        print("| scene | baseline s/spp | Mitsuba / baseline time | Lucent / baseline time | baseline RMSE |")
        print("|---|---:|---:|---:|---:|")
        for s in out:
            if "baseline_ratio_median" in s:
                print("| %s | %.4f | %.2f | %.3f | %.5f |" % (
                    s["scene"], s["baseline_s_per_spp"], s["baseline_ratio_median"],
                    s["lucent_over_baseline_median"], s["baseline_rmse_mean"]))


if __name__ == "__main__":
    cmd = sys.argv[1]
    if cmd == "average":
        average(sys.argv[2], sys.argv[3:])
    elif cmd == "blocks":
        blocks(sys.argv[2], sys.argv[3])
    elif cmd == "noise":
        noise(sys.argv[2], int(sys.argv[3]), sys.argv[4:])
    elif cmd == "summarize":
        summarize(sys.argv[2])
    elif cmd == "pair":
        pair(*sys.argv[2:5])
    elif cmd == "seeds_error":
        seeds_error(*sys.argv[2:6])
    elif cmd == "table":
        table(*sys.argv[2:4])
    else:
        sys.exit(__doc__)
