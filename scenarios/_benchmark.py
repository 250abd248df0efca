"""What the blind benchmarks (arm2, jet-pipe and the variant forms) share: the case lines they
print, the confusion-matrix plot and the metrics of the issue, from one row per case (``families``: the hidden families or ["none"];
``family_ok``, ``location_ok``, ``verdict``, ``nrmse_reduction``, ``seconds``, ``unexplained``)."""
from __future__ import annotations

import numpy as np


#: fresh base seeds of an evaluation run are 9-digit numbers: far from the small development seeds
FRESH_SEEDS = (100_000_000, 1_000_000_000)


def fresh_seed_base() -> int:
    """A base seed drawn from the operating system's entropy, in FRESH_SEEDS."""
    lo, hi = FRESH_SEEDS
    return lo + int(np.random.SeedSequence().entropy % (hi - lo))


def seed_base_from_env(env: str, development: int, out=None) -> tuple[int, str]:
    """(base seed, "development" | "given" | "fresh") from environment variable ``env``: unset,
    the development base; a whole number, that base; "fresh", one drawn from the operating
    system's entropy -- or, when ``out`` holds the ``seed.json`` of an unfinished run (no
    metrics.json yet), the one that run drew, so a resumed run keeps its seeds.  The caller
    writes ``seed.json`` (:func:`remember_seed_base`)."""
    import os

    from pneumatics.errors import ConfigError

    given = os.environ.get(env)
    if given is None:
        return development, "development"
    if given.strip().lower() == "fresh":
        return (None if out is None else stored_seed_base(out)) or (fresh_seed_base(), "fresh")
    try:
        return int(given), "given"
    except ValueError:
        raise ConfigError(f"{env}={given!r}: expected a whole number (the base seed) or 'fresh'") from None


def stored_seed_base(out) -> tuple[int, str] | None:
    """(base seed, source) an unfinished run into ``out`` drew (its ``seed.json``, no
    metrics.json yet), or None."""
    import json

    stored = out / "seed.json"
    if stored.is_file() and not (out / "metrics.json").exists():
        s = json.loads(stored.read_text())
        return int(s["seed_base"]), s["seed_source"]
    return None


def remember_seed_base(out, base: int, source: str) -> None:
    """``out``/seed.json: the base seed a run uses (a resumed fresh run reads it back)."""
    from pneumatics.io import atomic_write_json

    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "seed.json", {"seed_base": base, "seed_source": source})


def judge(effects: list[dict], report: dict, same=lambda named, hidden: named == hidden, strict: bool = False) -> dict:
    """One case's answer against its hidden ``effects`` ([{"family", "where"}]): every hidden
    family named (``same``), a not-separable alternative counting, and no finding of a family
    that was not hidden (family_ok); every hidden effect at a place a hit names (location_ok; a
    place listed as not separable counts unless ``strict``, which also takes ``same`` strictly)."""
    true_fams = [e["family"] for e in effects]
    ok_fam, ok_loc = [], []
    for e in effects:
        hits = [f for f in report["findings"] if any(same(n, e["family"]) for n in [f["effect"], *f.get("alternatives", [])])]
        ok_fam.append(bool(hits))
        places = [[f["where"]] if strict else [f["where"], *f.get("alternative_places", [])] for f in hits]
        ok_loc.append(any(e["where"] in p for p in places))
    extra = [f["effect"] for f in report["findings"]
             if not any(same(n, t) for n in [f["effect"], *f.get("alternatives", [])] for t in true_fams)]
    return {"family_ok": all(ok_fam) and not extra, "location_ok": all(ok_loc), "extra": extra,
            "named": [f["effect"] for f in report["findings"]]}


def nrmse_reductions(findings: list[dict], key: str = "heldout_nrmse") -> list[float]:
    """1 - after / before of each finding's held-out NRMSE on its channel (``key``
    "heldout_nrmse": the whole held-out data; "heldout_nrmse_in_regime": inside its regime)."""
    return [1 - f[key]["after"] / f[key]["before"] for f in findings if f.get(key) and f[key]["before"]]


def print_cases(rows: list[dict]) -> None:
    for r in rows:
        print(f"  case {r['seed']} {'+'.join(r['families'])}: named {r['named'] or ['nothing']}"
              f"{' + unexplained' if r['unexplained'] else ''} ({r['seconds']:.0f} s)")


def common_metrics(rows: list[dict], min_r2_key: str) -> dict:
    """effect_accuracy (all hidden families named, no other), two_effect_accuracy, location_accuracy
    (among cases with the families right), median_heldout_nrmse_reduction (finding's channel;
    _in_regime: inside the finding's located regime),
    null_false_discovery_rate, seconds_per_case, concealed_fraction (``min_r2_key`` >= 0.9)."""
    effect_rows = [r for r in rows if r["families"] != ["none"]]
    null_rows = [r for r in rows if r["families"] == ["none"]]
    two_rows = [r for r in effect_rows if len(r["families"]) > 1]
    fam_ok = [r for r in effect_rows if r["family_ok"]]
    reductions = [x for r in effect_rows for x in r["nrmse_reduction"]]
    in_regime = [x for r in effect_rows for x in r.get("nrmse_reduction_in_regime", [])]
    return {
        "cases": len(rows),
        "effect_accuracy": len(fam_ok) / max(len(effect_rows), 1),
        "two_effect_cases": len(two_rows),
        **({"two_effect_accuracy": sum(r["family_ok"] for r in two_rows) / len(two_rows)} if two_rows else {}),
        "location_accuracy": sum(r["location_ok"] for r in fam_ok) / max(len(fam_ok), 1),
        "median_heldout_nrmse_reduction": float(np.median(reductions)) if reductions else 0.0,
        "median_heldout_nrmse_reduction_in_regime": float(np.median(in_regime)) if in_regime else 0.0,
        "null_false_discovery_rate": sum(r["verdict"] != "no_significant_mismatch" for r in null_rows) / max(len(null_rows), 1),
        "seconds_per_case": float(np.mean([r["seconds"] for r in rows])),
        "concealed_fraction": float(np.mean([r[min_r2_key] >= 0.9 for r in effect_rows])) if effect_rows else 1.0,
    }


def confusion_matrix(rows: list[dict], hidden: list[str], cols: list[str], same=lambda named, hid: named == hid) -> np.ndarray:
    """Counts (len(hidden), len(cols)): a case's hidden families (``row["families"]``, ["none"]
    for a null case) in rows, what the doctor named (``row["named"]``, empty: "none") in
    columns; a name not in ``cols`` goes to the last column.

    A hidden family the doctor named (``same``) goes on its name's column; the names left over
    are shared among the hidden families it missed or, if it missed none, among all of the
    case's rows, so an extra finding beside a right one shows off the diagonal of a hit row."""
    mat = np.zeros((len(hidden), len(cols)))
    col = lambda n: cols.index(n) if n in cols else len(cols) - 1  # noqa: E731
    for r in rows:
        named = r["named"] or ["none"]
        fams = r["families"]
        extra = [n for n in named if not any(same(n, t) for t in fams)]
        hits = {t: next((n for n in named if same(n, t)), None) for t in fams}
        missed = [t for t, n in hits.items() if n is None]
        for t, n in hits.items():
            if n is not None:
                mat[hidden.index(t), col(n)] += 1
        share = extra or ["none"]
        for t in missed or (fams if extra else []):
            for n in share:
                mat[hidden.index(t), col(n)] += 1 / len(share) / (1 if missed else len(fams))
    return mat


def plot_confusion(ctx, mat: np.ndarray, hidden: list[str], named: list[str], title: str) -> None:
    """confusion_matrix.png: ``mat`` (len(hidden), len(named)) counts, hidden families in rows,
    what the doctor named in columns; fractions where a case's names were shared."""
    from .common import plt

    fig, ax = plt.subplots(figsize=(9, 7))
    ax.imshow(mat, cmap="Blues")
    ax.set_xticks(range(len(named)), named, rotation=60, ha="right", fontsize=8)
    ax.set_yticks(range(len(hidden)), hidden, fontsize=8)
    for i in range(len(hidden)):
        for k in range(len(named)):
            if mat[i, k]:
                ax.text(k, i, f"{mat[i, k]:.0f}" if mat[i, k] == int(mat[i, k]) else f"{mat[i, k]:.1f}",
                        ha="center", va="center", fontsize=8, color="white" if mat[i, k] > 0.5 * mat.max() else "black")
    ax.set_xlabel("named by the doctor")
    ax.set_ylabel("hidden in the recording")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    ctx.savefig(fig, "confusion_matrix.png")
