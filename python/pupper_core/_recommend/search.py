"""`pupper recommend`'s search: candidates are per-group (kp, kd); each is
checked against the loop margins first (cheap: the linearised joint, no
simulation), then run on every drawn robot at once (one sweep, the robots
drawn alike for every candidate), and judged by its worst-side push dip
under its constraints (the stand task; another ranks by its own measure,
`plan.Task`). Optuna's TPE (its constraints function, a sampler
seeded per generation) asks; the best feasible candidate is then polished
by its neighbours."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core._recommend.plan import NEIGHBOUR, Group, Plan, Task

#: What a candidate that cannot be ranked is told.
PENALTY = 1e6
#: Scores (push dips, with the stand task) within this share of each other are a tie: the candidate
#: whose slowest joint group tracks fastest (highest natural frequency,
#: sqrt(kp/J)) wins, since the push barely tells some groups' gains apart.
TIE = 0.02

Gains = dict[str, tuple[float, float]]


@dataclass
class Candidate:
    """One per-group setting of the gains and what it scored."""

    gains: Gains
    phase_deg: dict[str, float] = field(default_factory=dict)
    gain_db: dict[str, float] = field(default_factory=dict)
    #: the constraint it breaks first, in words; "" when it holds them all
    failed: str = ""
    p95_dip_mm: float = math.nan
    fell: int = 0
    robots: int = 0
    max_saturation: float = math.nan
    p95_peak_torque: float = math.nan
    #: the lowest final base height over the robots (m): how far the
    #: softest-standing robot sags
    min_height_m: float = math.nan
    cell_steps: int = 0
    number: int = -1
    #: "search" (asked by the sampler) or "polish" (a neighbour of a pick)
    stage: str = "search"
    #: what the rule ranks, lower wins: the task's measure (the stand
    #: task's p95 push dip)
    score: float = math.nan
    #: a task's own figures over the robots, each its worst side (the walk
    #: task's), as trials.csv names them
    figures: dict[str, float] = field(default_factory=dict)

    @property
    def feasible(self) -> bool:
        return not self.failed and math.isfinite(self.score)

    def row(self, groups: Sequence[Group], task: Task) -> dict[str, Any]:
        out: dict[str, Any] = {"trial": self.number, "stage": self.stage}
        for g in groups:
            out[f"kp.{g.name}"], out[f"kd.{g.name}"] = self.gains[g.name]
        for g in groups:
            out[f"phase_margin_deg.{g.name}"] = self.phase_deg.get(g.name, math.nan)
            out[f"gain_margin_db.{g.name}"] = self.gain_db.get(g.name, math.nan)
        out.update(task.row(self))
        out.update({"fell": self.fell, "robots": self.robots,
                    "max_saturation": self.max_saturation, "min_height_m": self.min_height_m,
                    "p95_peak_torque": self.p95_peak_torque,
                    "cell_steps": self.cell_steps, "status": "ok" if self.feasible else self.failed})
        return out


def margins(plan: Plan, g: Group, kp: float, kd: float) -> tuple[float, float]:
    """The worst phase (deg) and gain (dB) margin of a group's loops
    (``Group.loops``: its joints as each kind of motor delivers the gains,
    lightest and heaviest, or with a fit on every robot its logs allow)
    times the spread's motor gains, through the firmware's feedback path
    (the sensing delay given, else each joint's own fitted latency)."""
    from pupper_core._native import loop_margins

    worst_p, worst_g = math.inf, math.inf
    for lp in g.loops:
        for fp in set(plan.kp_factors):
            for fd in set(plan.kd_factors):
                p, d = loop_margins(lp.inertia, kp * fp * lp.kp_scale, kd * fd * lp.kd_scale, motor=plan.motor,
                                    sensing_delay=plan.sensing_delay, timestep=plan.timestep,
                                    damping=lp.damping, lag=lp.lag, latency=lp.latency, fitted=plan.calibrated)
                # a loop without margins (NaN) is the worst of all, never skipped by min()
                worst_p = p if not p >= worst_p else worst_p
                worst_g = d if not d >= worst_g else worst_g
    return worst_p, worst_g


def check_margins(plan: Plan, c: Candidate) -> None:
    """Fills the candidate's margins; says the first that falls short."""
    for g in plan.groups:
        kp, kd = c.gains[g.name]
        pm, gm = margins(plan, g, kp, kd)
        c.phase_deg[g.name], c.gain_db[g.name] = pm, gm
        if not c.failed and not pm >= plan.min_phase_margin:
            c.failed = f"{g.name} phase margin {_below(pm, plan.min_phase_margin)}° < {plan.min_phase_margin:g}°"
        elif not c.failed and not gm >= plan.min_gain_margin:
            c.failed = f"{g.name} gain margin {_below(gm, plan.min_gain_margin)} dB < {plan.min_gain_margin:g} dB"


def _below(v: float, limit: float) -> str:
    """A value under its limit, with the digits that show it under
    (29.98 reads 29.98, not 30.0)."""
    for digits in (1, 2, 3):
        text = f"{v:.{digits}f}"
        if float(text) < limit:
            return text
    return f"{v:.4g}"


#: The grid a group's margin map is computed on (log kp x log kd).
MAP_POINTS = 24


@dataclass
class Window:
    """Where a group's margins hold: for each kp of a log grid, the kd
    interval (log-interpolated edges) whose worst-corner margins meet the
    limits; NaN where none does. Candidates are drawn inside it, so the
    search spends no simulation on gains whose loop would not hold."""

    kps: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def kp_span(self) -> tuple[float, float] | None:
        ok = np.flatnonzero(np.isfinite(self.lo))
        return None if ok.size == 0 else (float(self.kps[ok[0]]), float(self.kps[ok[-1]]))

    def kd_span(self, kp: float) -> tuple[float, float]:
        """The kd interval at kp (interpolated in log kp between rows that
        have one)."""
        ok = np.isfinite(self.lo)
        x = np.log(self.kps[ok])
        lo = float(np.exp(np.interp(math.log(kp), x, np.log(self.lo[ok]))))
        hi = float(np.exp(np.interp(math.log(kp), x, np.log(self.hi[ok]))))
        return lo, max(hi, lo)


def _slack(plan: Plan, g: Group, kp: float, kd: float) -> float:
    """How far inside its limits a group's loop is (> 0: both margins hold;
    a decibel weighs as 5 degrees, only the sign and the zero matter)."""
    pm, gm = margins(plan, g, kp, kd)
    return min(pm - plan.min_phase_margin, 5 * (gm - plan.min_gain_margin))


#: Golden-section and bisection steps that refine a row's best kd and its
#: interval's edges between the map's grid points.
REFINE_STEPS = 16


def _row(plan: Plan, g: Group, kp: float, kds: np.ndarray) -> tuple[float, float] | None:
    """The kd interval at kp whose margins hold, or None: the slack on the
    kd grid, its peak refined between grid points (golden section in log
    kd: near the stiffest kp the interval is narrower than the grid's
    step), and each edge bisected where the slack crosses zero."""
    lx = np.log(kds)
    slack = lambda x: _slack(plan, g, kp, math.exp(x))  # noqa: E731
    s = np.array([slack(x) for x in lx])
    i = int(np.argmax(s))
    a, b = lx[max(i - 1, 0)], lx[min(i + 1, len(lx) - 1)]
    peak, top = lx[i], s[i]
    r = (math.sqrt(5) - 1) / 2
    for _ in range(REFINE_STEPS):
        c, d = b - r * (b - a), a + r * (b - a)
        sc, sd = slack(c), slack(d)
        if sc > sd:
            b = d
            if sc > top:
                peak, top = c, sc
        else:
            a = c
            if sd > top:
                peak, top = d, sd
    if not top > 0:
        return None

    def edge(outside: float) -> float:
        good, bad = peak, outside
        for _ in range(REFINE_STEPS):
            mid = 0.5 * (good + bad)
            good, bad = (mid, bad) if slack(mid) > 0 else (good, mid)
        return good

    # the first grid point each side where the margins fail, else the range's end
    below = [x for x, v in zip(lx, s) if x < peak and not v > 0]
    above = [x for x, v in zip(lx, s) if x > peak and not v > 0]
    lo = edge(below[-1]) if below else lx[0]
    hi = edge(above[0]) if above else lx[-1]
    return math.exp(lo), math.exp(hi)


#: Halvings of the log-kp step that find where a window's span ends
#: between two grid rows (the stiffest gains whose margins hold).
EDGE_STEPS = 8


def window(plan: Plan, g: Group) -> Window:
    """The group's margin map on a MAP_POINTS² log grid, each row's kd
    interval, and the span's ends found between grid rows by bisection: a
    pick on its margin limit is often its stiffest kp, which the grid's
    step (a factor of about 1.26) would otherwise cut short."""
    kps = list(np.geomspace(*g.kp_range, MAP_POINTS))
    kds = np.geomspace(*g.kd_range, MAP_POINTS)
    rows = [_row(plan, g, float(kp), kds) for kp in kps]
    ok = [i for i, r in enumerate(rows) if r is not None]
    if ok:
        for inside, outside in ((ok[-1], ok[-1] + 1), (ok[0], ok[0] - 1)):
            if not 0 <= outside < MAP_POINTS:
                continue
            good, bad, found = math.log(kps[inside]), math.log(kps[outside]), rows[inside]
            for _ in range(EDGE_STEPS):
                mid = 0.5 * (good + bad)
                r = _row(plan, g, math.exp(mid), kds)
                if r is None:
                    bad = mid
                else:
                    good, found = mid, r
            kps.append(math.exp(good))
            rows.append(found)
    order = np.argsort(kps)
    nan = (math.nan, math.nan)
    return Window(np.array(kps)[order], np.array([(rows[i] or nan)[0] for i in order]),
                  np.array([(rows[i] or nan)[1] for i in order]))


def _cell(plan: Plan, gains: Gains, name: str) -> dict[str, float | str]:
    cell: dict[str, float | str] = {"name": name}
    for g in plan.groups:
        cell[f"kp.{g.name}"], cell[f"kd.{g.name}"] = gains[g.name]
    return cell


def simulate(plan: Plan, cands: Sequence[Candidate], robot_models: Sequence[str],
             say: Callable[[str], None], own_gains: bool = False) -> None:
    """Runs the candidates (margins already checked) on every drawn robot,
    the robots drawn alike for every candidate, as the task runs them (the
    stand task: one sweep per joint model, the push): fills each one's
    score, falls, saturation and peak torque, and judges it."""
    plan.task.simulate(plan, cands, robot_models, say, own_gains)


def judge(plan: Plan, c: Candidate, unmeasured: str) -> None:
    """The constraint a simulated candidate breaks first, in words ("" when
    it holds them all); `unmeasured` when its score is missing."""
    if c.fell:
        c.failed = f"{c.fell} of {c.robots} robots fell, diverged or lay past the stability bound"
    elif not c.max_saturation < plan.max_saturation:
        c.failed = (f"saturated {100 * c.max_saturation:.1f} % of steps on its worst robot "
                    f"(limit {100 * plan.max_saturation:g} %)")
    elif plan.sags(c.min_height_m):
        c.failed = (f"sags to {1000 * c.min_height_m:.1f} mm on its lowest robot, "
                    f"{100 * c.min_height_m / plan.stance:.1f} % of its {1000 * plan.stance:.1f} mm stance "
                    f"(limit {100 * (1 - plan.max_sag):g} %)")
    elif not math.isfinite(c.score):
        c.failed = unmeasured


def _sampler(optuna: Any, seed: int, generation: int, batch: int) -> Any:
    """TPE seeded from (seed, generation); each trial's constraint (set
    with `Trial.set_constraint`) teaches it where the robots' limits hold."""
    s = int.from_bytes(np.random.SeedSequence([seed, generation]).generate_state(1).tobytes()[:4], "little")
    return optuna.samplers.TPESampler(seed=s, n_startup_trials=batch, multivariate=True)


def rounded(kp: float, kd: float) -> tuple[float, float]:
    """Gains as a robot's configuration holds them: four significant digits.
    Every candidate is rounded so, so the numbers pupper reports are those of
    the gains it exports."""
    return float(f"{kp:.4g}"), float(f"{kd:.4g}")


def _at(w: Window, kp: float, u: float) -> tuple[float, float]:
    """The gains at kp and a share u of the kd interval there (in log kd)."""
    lo, hi = w.kd_span(kp)
    return rounded(kp, lo * (hi / lo) ** u)


def _told(c: Candidate, plan: Plan, dists: Mapping[str, Any]) -> float:
    """What the sampler is told: the push dip, tilted by up to TIE toward
    the candidate whose softest group (its kp's place in its own searched
    span, in log) is stiffest, as the pick's tie rule prefers."""
    if not c.feasible:
        return PENALTY
    share = min((math.log(c.gains[g.name][0]) - math.log(dists[f"kp.{g.name}"].low))
                / max(math.log(dists[f"kp.{g.name}"].high / dists[f"kp.{g.name}"].low), 1e-12)
                for g in plan.groups)
    return c.score * (1 + TIE * (1 - min(max(share, 0.0), 1.0)))


def windows(plan: Plan) -> dict[str, Window]:
    """Each group's margin window."""
    return {g.name: window(plan, g) for g in plan.groups}


def _stiffest(plan: Plan, g: Group, w: Window, lo: float, hi: float) -> float:
    """The stiffest kp of the group's window (its kp span lo to hi) whose
    gains, kd mid-window and rounded as every candidate is, keep the
    margins: the window's top, or a hair below it where the rounding would
    step outside."""
    for f in (1.0, 1.002, 1.005, 1.01, 1.02, 1.05):
        kp = max(hi / f, lo)
        c = Candidate({g.name: _at(w, kp, 0.5)})
        pm, gm = margins(plan, g, *c.gains[g.name])
        if pm >= plan.min_phase_margin and gm >= plan.min_gain_margin:
            return kp
    return max(hi / 1.05, lo)


def search(plan: Plan, robot_models: Sequence[str], say: Callable[[str], None],
           after_generation: Callable[[list[Candidate]], None],
           wins: Mapping[str, Window] | None = None) -> list[Candidate]:
    """Generations of `batch` candidates whose margins hold (those that do
    not are told so at once, costing no simulation) until `trials` have
    run on the robots. Every candidate asked, in order."""
    from pupper_core._tune.plan import _optuna

    optuna = _optuna()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="minimize")
    wins = windows(plan) if wins is None else wins
    dists = {}
    for g in plan.groups:
        span = wins[g.name].kp_span()
        if span is None:
            say(f"no gains of the {g.name} group keep its margins over the searched range "
                f"(kp {g.kp_range[0]:.3g} to {g.kp_range[1]:.3g}, kd {g.kd_range[0]:.3g} to {g.kd_range[1]:.3g})")
            return []
        # a range of one point is no range: the window's own grid step
        lo, hi = span if span[1] > span[0] else (span[0] / 1.1, span[0] * 1.1)
        dists[f"kp.{g.name}"] = optuna.distributions.FloatDistribution(lo, hi, log=True)
        dists[f"u.{g.name}"] = optuna.distributions.FloatDistribution(0.0, 1.0)
    # the first candidate: each group as stiff as its margins allow (the top
    # of its kp span, kd mid-window); in simulation stiffer stands firmer and
    # dips less up to the margins, so the search starts where a pick is likely
    study.enqueue_trial({**{f"kp.{g.name}": _stiffest(plan, g, wins[g.name], dists[f"kp.{g.name}"].low,
                                                     dists[f"kp.{g.name}"].high)
                            for g in plan.groups},
                         **{f"u.{g.name}": 0.5 for g in plan.groups}})
    every: list[Candidate] = []
    ran, generation = 0, 0
    while ran < plan.trials:
        study.sampler = _sampler(optuna, plan.seed, generation, plan.batch)
        want = min(plan.batch, plan.trials - ran)
        batch: list[tuple[Any, Candidate]] = []
        for _ in range(want * 50):  # asks are cheap; a region with no margin yields nothing
            t = study.ask(dists)
            c = Candidate({g.name: _at(wins[g.name], t.params[f"kp.{g.name}"], t.params[f"u.{g.name}"])
                           for g in plan.groups}, number=len(every))
            every.append(c)
            check_margins(plan, c)
            if c.failed:  # an edge the map's interpolation put a hair outside
                t.set_constraint("margins", 1.0)
                t.set_constraint("robots", 1.0)
                study.tell(t, PENALTY)
                continue
            batch.append((t, c))
            if len(batch) == want:
                break
        if not batch:
            break
        simulate(plan, [c for _, c in batch], robot_models, say)
        for t, c in batch:
            t.set_constraint("margins", 0.0)
            t.set_constraint("robots", 0.0 if c.feasible else 1.0)
            study.tell(t, _told(c, plan, dists))
        ran += len(batch)
        generation += 1
        after_generation(every)
        best = best_of(plan, every)
        say(f"generation {generation}: {ran} candidates on {plan.robots} robots"
            + (f"; best {plan.task.says(best.score)}" if best else "; none holds every constraint yet"))
    return every


def slowest_hz(plan: Plan, c: Candidate) -> float:
    """The lowest natural frequency (Hz) of the candidate's groups, on the
    kp their motors deliver (the least of it)."""
    return min(math.sqrt(c.gains[g.name][0] * g.kp_scale[0] / g.inertia[1]) / (2 * math.pi) for g in plan.groups)


def better(plan: Plan, a: Candidate, b: Candidate) -> bool:
    """Whether feasible `a` beats feasible `b`: a lower score (push dip) by
    more than TIE; within TIE, a faster slowest group; as fast, a lower
    score."""
    if a.score < b.score * (1 - TIE):
        return True
    if a.score > b.score * (1 + TIE):
        return False
    fa, fb = slowest_hz(plan, a), slowest_hz(plan, b)
    return fa > fb or (fa == fb and a.score < b.score)


def best_of(plan: Plan, cands: Sequence[Candidate]) -> Candidate | None:
    """The pick among candidates: those within TIE of the lowest score
    (push dip) tie; the fastest slowest group among them wins, then the
    lower score, then the one asked first."""
    ok = [c for c in cands if c.feasible]
    if not ok:
        return None
    low = min(c.score for c in ok)
    near = [c for c in ok if c.score <= low * (1 + TIE)]
    return max(near, key=lambda c: (slowest_hz(plan, c), -c.score, -c.number))


def gains_key(gains: Mapping[str, tuple[float, float]]) -> tuple[Any, ...]:
    """Gains as a key: equal for the same gains, whatever the group order."""
    return tuple(sorted(gains.items()))


def tradeoffs(plan: Plan, cands: Sequence[Candidate]) -> list[Candidate]:
    """The trade-off set: feasible candidates no other beats at once on the
    score (push dip, lower), the slowest group's tracking (faster) and the stand
    height (higher), ordered by score. The pick is one of them whenever
    it stands no lower than its ties."""
    # the same gains asked twice (the polish's way back) count once, the first
    firsts: dict[tuple[Any, ...], Candidate] = {}
    for c in cands:
        if c.feasible:
            firsts.setdefault(gains_key(c.gains), c)
    ok = list(firsts.values())
    keys = [(c.score, -slowest_hz(plan, c), -c.min_height_m) for c in ok]

    def beaten(k: tuple[float, ...]) -> bool:
        return any(all(a <= b for a, b in zip(o, k)) and o != k for o in keys)

    front = {id(c): c for c, k in zip(ok, keys) if not beaten(k)}
    return sorted(front.values(), key=lambda c: (c.score, c.number))


def _along(w: Window, kp: float, kd: float, to: float) -> tuple[float, float] | None:
    """The gains at kp `to` with kd where it sits at kp in the margin window
    (the same share of it, in log): a move along the window, where a pick
    on its margin limit has its better neighbours. None outside the span."""
    span = w.kp_span()
    if span is None or not span[0] <= to <= span[1]:
        return None
    lo, hi = w.kd_span(kp)
    u = min(max(math.log(kd / lo) / math.log(hi / lo), 0.0), 1.0) if hi > lo else 0.5
    return _at(w, to, u)


def neighbours(plan: Plan, pick: Candidate, wins: Mapping[str, Window] | None = None) -> list[tuple[str, Candidate]]:
    """The pick with one group's kp or kd NEIGHBOUR times higher or lower,
    and (given the margin windows) its kp so moved with kd along the
    window, inside the searched ranges: what the card says lost, and why."""
    out = []
    for g in plan.groups:
        kp, kd = pick.gains[g.name]
        moves: list[tuple[str, tuple[float, float] | None]] = [
            (f"kp.{g.name} ×{NEIGHBOUR:g}", rounded(kp * NEIGHBOUR, kd)),
            (f"kp.{g.name} ÷{NEIGHBOUR:g}", rounded(kp / NEIGHBOUR, kd)),
            (f"kd.{g.name} ×{NEIGHBOUR:g}", rounded(kp, kd * NEIGHBOUR)),
            (f"kd.{g.name} ÷{NEIGHBOUR:g}", rounded(kp, kd / NEIGHBOUR))]
        if wins is not None:
            for sign, f in (("×", NEIGHBOUR), ("÷", 1 / NEIGHBOUR)):
                moves.append((f"kp.{g.name} {sign}{NEIGHBOUR:g} along its margin window",
                               _along(wins[g.name], kp, kd, kp * f)))
        seen = {pick.gains[g.name]}
        for label, gk in moves:
            if gk is None or gk in seen:
                continue
            seen.add(gk)
            if not (g.kp_range[0] <= gk[0] <= g.kp_range[1] and g.kd_range[0] <= gk[1] <= g.kd_range[1]):
                continue
            out.append((label, Candidate({**pick.gains, g.name: gk})))
    return out


def polish(plan: Plan, pick: Candidate, robot_models: Sequence[str], say: Callable[[str], None],
           every: list[Candidate], wins: Mapping[str, Window] | None = None
           ) -> tuple[Candidate, list[tuple[str, Candidate]]]:
    """Moves the pick to a better feasible neighbour while there is one (at
    most `plan.polish` times); the final pick and its neighbours, each
    scored (and appended to `every`)."""
    near: list[tuple[str, Candidate]] = []
    held = {gains_key(pick.gains)}
    for r in range(plan.polish + 1):
        near = neighbours(plan, pick, wins)
        # gains already run on these robots (the pick a move ago) are not run again
        known = {gains_key(c.gains): c for c in every if c.robots}
        for _, c in near:
            c.number, c.stage = len(every), "polish"
            every.append(c)
            check_margins(plan, c)
            old = known.get(gains_key(c.gains))
            if old is not None and not c.failed:
                c.p95_dip_mm, c.fell, c.robots, c.failed = old.p95_dip_mm, old.fell, old.robots, old.failed
                c.max_saturation, c.p95_peak_torque, c.min_height_m = (old.max_saturation, old.p95_peak_torque,
                                                                       old.min_height_m)
                c.score, c.figures = old.score, dict(old.figures)
        simulate(plan, [c for _, c in near if not c.failed and not c.robots], robot_models, say)
        # a move back to a pick already held would go round in circles
        won = best_of(plan, [pick] + [c for _, c in near if gains_key(c.gains) not in held])
        if won is None or won is pick or r == plan.polish:
            return pick, near
        held.add(gains_key(won.gains))
        value = plan.task.value
        say(f"polish: a neighbour holds every constraint at a {plan.task.objective} of {value(won.score)} "
            f"(the pick's {value(pick.score)}), its slowest group at {slowest_hz(plan, won):.3g} Hz: moved there")
        pick = won
    return pick, near


def why_lost(plan: Plan, label: str, c: Candidate, pick: Candidate) -> str:
    """A neighbour's reason, in words."""
    if c.failed:
        return f"{label}: {c.failed}"
    what, value, says = plan.task.measure, plan.task.value, plan.task.says
    if better(plan, c, pick):
        if c.score < pick.score * (1 - TIE):
            how = f"a lower {what}"
        elif slowest_hz(plan, c) > slowest_hz(plan, pick):
            how = f"a tie on the {what}, with a faster slowest group"
        else:
            how = f"a tie on the {what} at the same slowest group, and a lower {what.split()[-1]}"
        return (f"{label}: would win ({how}: {value(c.score)} against {value(pick.score)}); the polish "
                "had made its last move (--polish), so the pick may lie short of the best")
    if c.score <= pick.score * (1 + TIE):
        fc, fp = slowest_hz(plan, c), slowest_hz(plan, pick)
        if fc < fp:
            return (f"{label}: {says(c.score)} ties the pick's {value(pick.score)}, and "
                    f"its slowest group tracks slower ({fc:.3g} Hz against {fp:.3g})")
        return (f"{label}: {says(c.score)} ties the pick's {value(pick.score)} "
                "at the same slowest group, and is not lower")
    return f"{label}: {says(c.score)}, above the pick's {value(pick.score)}"


def robot_model_files(plan: Plan, out: Path) -> list[str]:
    """The joint models the robots are drawn on: the model itself, or with
    --from-fit one MJCF per robot its logs allow (the fit's robots.csv),
    written into out/robots/ and kept: a sweep reproduces any robot from it."""
    if not plan.fit_robots:
        return [plan.model]
    from pupper_core._recommend.fits import robot_xml

    out.mkdir(parents=True, exist_ok=True)
    files = []
    for k, values in enumerate(plan.fit_robots):
        path = out / f"robot_{k}.xml"
        path.write_text(robot_xml(plan.model, plan.fit_rows, values))
        files.append(str(path))
    return files


def gains_per_actuator(plan: Plan, gains: Mapping[str, tuple[float, float]]) -> list[tuple[float, float]]:
    """Each actuator's (kp, kd), in the model's order."""
    out = [(math.nan, math.nan)] * len(plan.actuators)
    for g in plan.groups:
        for a in g.actuators:
            out[a] = gains[g.name]
    return out
