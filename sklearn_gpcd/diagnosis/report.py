"""The diagnosis report: plain-words text, JSON and figure."""

import json
from dataclasses import dataclass, field

import numpy as np

from .._atomic import atomic_write
from .effects import _joint_list
from .selection import separating_excitation

#: t-statistic thresholds of the words used for the evidence.
CONFIDENCE_WORDS = ((10.0, "very strong"), (5.0, "strong"), (0.0, "moderate"))


def confidence(t):
    """Plain word for a t-statistic of the held-out gains.

    Examples
    --------
    >>> confidence(12.0), confidence(6.0), confidence(3.5)
    ('very strong', 'strong', 'moderate')
    """
    t = np.inf if t is None else t
    for threshold, word in CONFIDENCE_WORDS:
        if t >= threshold:
            return word
    return "weak"


def relative_change(before, after):
    """A change of a loss in plain words: ``"0.29 -> 0.05, 83 % lower"``.

    Parameters
    ----------
    before, after : float
        The loss (e.g. nMSE) before and after.

    Returns
    -------
    text : str

    Examples
    --------
    >>> relative_change(0.29, 0.05)
    '0.29 -> 0.05, 83 % lower'
    >>> relative_change(0.1, 0.217)
    '0.1 -> 0.217, 117 % higher'
    >>> relative_change(0.1, 0.1)
    '0.1 -> 0.1, unchanged'
    >>> relative_change(7.2, 0.0099)
    '7.2 -> 0.0099, 99.9 % lower'
    >>> relative_change(0.2174, 9.866e-05)
    '0.2174 -> 9.866e-05, 99.95 % lower'
    >>> relative_change(0.5, 0.0)
    '0.5 -> 0, 100 % lower'
    """
    head = f"{before:.4g} -> {after:.4g}"
    if not before > 0:
        return head
    change = 100.0 * (after - before) / before
    if abs(change) < 0.5:
        return f"{head}, unchanged"
    size, decimals = abs(change), 0
    while size < 100 and round(size, decimals) >= 100 and decimals < 4:
        decimals += 1  # never "100 % lower" when something is left
    size = f"{size:.{decimals}f}"
    return f"{head}, {size} % {'lower' if change < 0 else 'higher'}"


#: How the JSON counts joints and links (people's text counts from 1).
JSON_SCHEMA_NOTE = {
    "joints": "0-based joint indices in this JSON (joint 0 is the base joint); the text "
              "report counts joints from 1",
    "link": "0-based link index (link k moves with joint k)",
    "nmse_before/nmse_after": "one value per joint, in joint order",
}


def _num(x):
    x = float(x)
    return None if not np.isfinite(x) else x


def _group(effects):
    """Per-joint effects of one name merged; shared effects kept apart."""
    groups = {}
    for fitted in effects:
        key = fitted.name if fitted.effect.per_joint else (fitted.name, fitted.target)
        groups.setdefault(key, []).append(fitted)
    return list(groups.values())


def _entry(group):
    """JSON entry of a group of fitted effects (see DiagnosisReport.to_dict)."""
    first = group[0]
    effect = first.effect
    names = effect.parameter_names
    units = dict(zip(names, effect.units))
    explained = sum(f.explained_ss for f in group)
    nominal = sum(f.nominal_ss for f in group)
    evidence = [f.evidence.to_dict() if f.evidence is not None else {} for f in group]
    if effect.per_joint:
        order = np.argsort([f.target for f in group])
        group = [group[i] for i in order]
        evidence = [evidence[i] for i in order]
        joints = [int(f.target) for f in group]
        params = {n: [_num(f.parameters[n][0]) for f in group] for n in names}
        stds = {n: [_num(f.parameters[n][1]) for f in group] for n in names}
        keys = evidence[0].keys() if evidence and evidence[0] else []
        ev = {k: [e.get(k) for e in evidence] for k in keys}
        ev["criterion"] = evidence[0].get("criterion") if evidence and evidence[0] else None
    else:
        joints = [int(j) for j in first.joints]
        params = {n: _num(first.parameters[n][0]) for n in names}
        stds = {n: _num(first.parameters[n][1]) for n in names}
        ev = evidence[0]
    entry = {
        "name": effect.name,
        "joints": joints,
        "parameters": params,
        "uncertainty": stds,
        "units": units,
        "explained_variance": _num(explained / nominal) if nominal > 0 else None,
        "evidence": ev,
        "description": "; ".join(f.effect.sentence(f.parameters, [f.target] if f.effect.per_joint
                                                    else f.joints) for f in group),
    }
    if effect.target_kind == "link":
        entry["link"] = int(first.target)
    ts = [f.evidence.t for f in group if f.evidence is not None]
    entry["confidence"] = confidence(min(ts)) if ts else None
    return entry


def _stability_lines(entry):
    """One line on the block-bootstrap evidence of a report entry."""
    st = entry.get("stability")
    if not st or not st["inclusion"]:
        return []
    parts = []
    joints = entry["joints"] if len(st["inclusion"]) == len(entry["joints"]) else [None]
    for j, p, size, gain in zip(joints, st["inclusion"], st["size_interval"],
                                st["heldout_gain_interval"]):
        where = "" if j is None or len(joints) == 1 else f"joint {j + 1}: "
        text = f"{where}named in {100 * (p or 0):.0f} % of resamples"
        if size:
            text += f", size {size[0]:.3g} to {size[2]:.3g}"
        if gain:
            text += f", held-out gain {100 * gain[0]:.0f}-{100 * gain[2]:.0f} %"
        parts.append(text)
    lines = ["      Block bootstrap (95 % intervals): " + "; ".join(parts) + "."]
    return lines + _recording_gain_lines(entry, joints)


def _recording_gain_lines(entry, joints):
    """One line: the held-out gain of the effect on each training recording."""
    names = entry["stability"].get("recordings") or []
    per = entry["stability"].get("heldout_gain_per_recording") or []
    parts = []
    for j, gains in zip(joints, per):
        if not gains:
            continue
        where = "" if j is None or len(joints) == 1 else f"joint {j + 1}: "
        parts.append(where + ", ".join(
            f"{name} {'-' if g is None else f'{100 * g:.0f} %'}"
            for name, g in zip(names or [f"recording {k + 1}" for k in range(len(gains))],
                               gains)))
    if not parts:
        return []
    return ["      Held-out gain per recording (given the other effects): "
            + "; ".join(parts) + "."]


@dataclass
class DiagnosisReport:
    """What a :class:`DynamicsDiagnosis` found, for people and programs.

    Build it with :meth:`DynamicsDiagnosis.report`. ``str(report)`` is the
    plain-words text; :meth:`to_dict` / :meth:`to_json` the machine-readable
    form; :meth:`plot` the figure.

    Attributes
    ----------
    effects : list of dict
        One entry per named effect (per-joint effects of one kind merged):
        ``name``, ``joints`` (0-based), ``parameters`` and ``uncertainty``
        (value or list aligned with ``joints`` for per-joint effects),
        ``units``, ``explained_variance`` (share of the nominal residual's
        sum of squares on those joints the effect removes given the
        others), ``evidence`` (held-out gain, t-statistic, folds improved,
        BIC change), ``confidence`` and a plain-words ``description``.
    nmse_before, nmse_after : list of float
        Per-joint nMSE of the nominal and refined models (paper Eq. 18) on
        the held-out recordings while the joint moves (training recordings
        when ``heldout`` is False).
    nmse_before_all, nmse_after_all : list of float
        The same over every sample.
    heldout : bool
        Whether the nMSE comes from held-out recordings.
    summary : dict
        Robot, recordings, samples, candidates tested, timings.
    breakdown, breakdown_after : ResidualBreakdown
        Residual of the nominal and refined models on the training data.
    rejected : list of dict
        The strongest candidates that were not selected, with their evidence.
    implausible : list of dict
        Estimates rejected as physically implausible or insignificant, with
        the reason (``name``, ``effect``, ``joints`` 0-based, ``reason``).
    ambiguities : list of dict
        Effects the recordings cannot tell apart, with the excitation that
        would separate them (see ``DynamicsDiagnosis.ambiguities_``).
    unidentifiable : list of dict
        Effects the recordings could not show at a size that matters, with
        the excitation that would (see ``DynamicsDiagnosis.unidentifiable_``).
    identifiability : list of dict
        Per candidate family, from the information matrix of these
        recordings: smallest detectable size, condition and what it is
        confounded with (see ``DynamicsDiagnosis.identifiability_``).
    needs : list of dict
        What a new recording should show (``DynamicsDiagnosis.needs_``;
        ``gpcd diagnose --plan`` writes it).

    Examples
    --------
    >>> from sklearn_gpcd.diagnosis.report import DiagnosisReport
    >>> DiagnosisReport(effects=[], nmse_before=[0.1], nmse_after=[0.1]).to_dict()["effects"]
    []
    """

    effects: list
    nmse_before: list
    nmse_after: list
    nmse_before_all: list = None
    nmse_after_all: list = None
    heldout: bool = False
    summary: dict = field(default_factory=dict)
    breakdown: object = None
    breakdown_after: object = None
    rejected: list = field(default_factory=list)
    implausible: list = field(default_factory=list)
    ambiguities: list = field(default_factory=list)
    unidentifiable: list = field(default_factory=list)
    identifiability: list = field(default_factory=list)
    needs: list = field(default_factory=list)

    @classmethod
    def from_diagnosis(cls, diagnosis, scores=None):
        """Report of a fitted :class:`DynamicsDiagnosis`.

        Parameters
        ----------
        diagnosis : DynamicsDiagnosis
        scores : dict, default=None
            Output of :meth:`DynamicsDiagnosis.evaluate` on held-out data;
            None uses the training nMSE.

        Returns
        -------
        report : DiagnosisReport
        """
        effects = [_entry(g) for g in _group(diagnosis.effects_)]
        stable = getattr(diagnosis, "stability_", {})
        for e, group in zip(effects, _group(diagnosis.effects_)):
            rows = [stable.get((f.name, f.target), {}) for f in
                    sorted(group, key=lambda f: -1 if f.target is None else f.target)]
            e["stability"] = {"inclusion": [r.get("inclusion") for r in rows],
                              # its group of confounded alternatives (stability.py)
                              "group_inclusion": [r.get("group_inclusion") for r in rows],
                              "group": [{r["labels"][f]: p for f, p in r["group"].items()}
                                        if r.get("group") else None for r in rows],
                              "size_interval": [r.get("size") for r in rows],
                              "heldout_gain_interval": [r.get("gain") for r in rows],
                              "heldout_gain_per_recording": [r.get("recording_gains")
                                                             for r in rows],
                              "recordings": diagnosis.training_summary_["recordings"]}
        effects.sort(key=lambda e: -(e["explained_variance"] or 0.0))
        if scores is None:
            before, after = diagnosis.nmse_train_before_, diagnosis.nmse_train_after_
            scores = {"nmse_before": list(before), "nmse_after": list(after),
                      "recordings": diagnosis.training_summary_["recordings"]}
            heldout = False
        else:
            heldout = True
        nominal = diagnosis.nominal_
        last = diagnosis.history_[-1] if diagnosis.history_ else []
        rejected = sorted(last, key=lambda s: -s.relative_gain)[:3]
        summary = {
            "robot": nominal.robot.name,
            "torque_constants": [float(k) for k in nominal.torque_constants],
            "nominal_friction": nominal.friction is not None,
            "reference": ("refined model of an earlier diagnosis"
                          if getattr(diagnosis, "base_model", None) is not None else
                          "simulated runs" if diagnosis.training_summary_.get("alignment_lags")
                          else "nominal model"),
            "units": diagnosis.units_,
            "training": diagnosis.training_summary_,
            "test_recordings": scores.get("recordings"),
            "effects_tested": sorted({c.candidate.effect.name for steps in diagnosis.history_[:1]
                                      for c in steps}),
            "n_candidates": diagnosis.n_candidates_,
            "min_gain": diagnosis.min_gain,
            "min_t": diagnosis.min_t,
            "min_share": getattr(diagnosis, "min_share", None),
        }
        return cls(
            effects=effects,
            nmse_before=[_num(x) for x in scores["nmse_before"]],
            nmse_after=[_num(x) for x in scores["nmse_after"]],
            nmse_before_all=[_num(x) for x in scores.get("nmse_before_all", [])] or None,
            nmse_after_all=[_num(x) for x in scores.get("nmse_after_all", [])] or None,
            heldout=heldout, summary=summary, breakdown=diagnosis.breakdown_,
            breakdown_after=diagnosis.breakdown_after_,
            rejected=[{"name": s.candidate.label, **s.to_dict()} for s in rejected],
            implausible=list(getattr(diagnosis, "rejected_effects_", [])),
            ambiguities=list(getattr(diagnosis, "ambiguities_", [])),
            unidentifiable=list(getattr(diagnosis, "unidentifiable_", [])),
            identifiability=list(getattr(diagnosis, "identifiability_", [])),
            needs=list(getattr(diagnosis, "needs_", [])),
        )

    def to_dict(self):
        """JSON-ready dictionary of the report.

        Keys: ``schema`` (joints are 0-based here), ``effects``, ``nmse_before``,
        ``nmse_after``, ``rejected_estimates``, ``ambiguous`` and more.
        """
        out = {
            "schema": JSON_SCHEMA_NOTE,
            "effects": self.effects,
            "nmse_before": self.nmse_before,
            "nmse_after": self.nmse_after,
            "nmse_heldout": self.heldout,
        }
        if self.nmse_before_all is not None:
            out["nmse_before_all_samples"] = self.nmse_before_all
            out["nmse_after_all_samples"] = self.nmse_after_all
        out["summary"] = self.summary
        out["strongest_rejected"] = self.rejected
        out["rejected_estimates"] = self.implausible
        out["ambiguous"] = self.ambiguities
        out["not_identifiable"] = self.unidentifiable
        out["identifiability"] = self.identifiability
        out["needs"] = self.needs
        if self.breakdown is not None:
            out["residual_breakdown"] = self.breakdown.to_dict()
        return out

    def to_json(self, path=None, indent=2):
        """The JSON text; also written to ``path`` when given.

        Parameters
        ----------
        path : str or Path, default=None
        indent : int, default=2

        Returns
        -------
        text : str
        """
        text = json.dumps(self.to_dict(), indent=indent, default=_json_default)
        if path is not None:
            atomic_write(path, lambda handle: handle.write(text + "\n"), mode="w")
        return text

    def text(self):
        """The report in plain words for a robotics engineer."""
        s = self.summary
        train = s.get("training", {})
        units = s.get("units", "A")
        lines = [
            f"Diagnosis of the {s.get('robot', '?')} model against "
            f"{len(train.get('recordings', []))} recording(s) "
            f"({train.get('duration', 0):.1f} s, {train.get('n_samples', 0)} samples).",
            f"Reference: {s.get('reference', 'nominal model')}; nominal friction "
            + ("given." if s.get("nominal_friction")
               else "not given (friction counts as missing)."),
            "",
            "1. Where the model is wrong (residual RMS while each joint moves, training data):",
        ]
        b = self.breakdown
        if b is not None:
            for j in range(b.n_joints):
                cells = {k: v["share_of_error"][j] - v["share_of_samples"][j]
                         for k, v in b.regimes.items() if np.isfinite(v["share_of_error"][j])}
                worst = max(cells, key=cells.get) if cells else None
                where = ""
                if worst is not None and cells[worst] > 0.1:
                    cell = b.regimes[worst]
                    where = (f"; over all samples {100 * cell['share_of_error'][j]:.0f} % of "
                             f"its squared error comes from '{worst}' "
                             f"({100 * cell['share_of_samples'][j]:.0f} % of samples)")
                after = ""
                if self.breakdown_after is not None:
                    after = f" -> {self.breakdown_after.rms_moving[j]:.3g} {units} after"
                lines.append(f"   joint {j + 1}: {b.rms_moving[j]:.3g} {units}{after}{where}")
        lines += ["", "2. What is missing:"]
        if not self.effects:
            tested = ", ".join(s.get("effects_tested", []))
            lines.append(
                f"   Nothing. None of the {len(s.get('effects_tested', []))} effects tested "
                f"({tested}; {s.get('n_candidates', '?')} candidates over joints, links and "
                "settings) lowers the held-out error both reliably and by a practical amount "
                "with plausible parameters. The nominal model explains the "
                "data as far as these effects can tell.")
            if self.rejected:
                r = self.rejected[0]
                lines.append(
                    f"   Closest call: {r['name']} would remove "
                    f"{100 * r['relative_gain']:.1f} % of the held-out error of its joints "
                    f"(t = {r['t_statistic'] or float('nan'):.1f}, lower in "
                    f"{r['folds_improved']} folds, "
                    f"{100 * (r.get('share_of_nominal_residual') or 0):.2g} % of the nominal "
                    f"residual; naming needs >= {100 * s.get('min_gain', 0):.0f} %, t >= "
                    f"{s.get('min_t', 0):g} or every fold, >= "
                    f"{100 * (s.get('min_share') or 0):g} % of the residual and plausible "
                    "parameters).")
        for k, e in enumerate(self.effects, 1):
            ev = e["evidence"]
            t = ev.get("t_statistic")
            t_min = min(x for x in t if x is not None) if isinstance(t, list) else t
            rel = ev.get("relative_gain")
            rel = min(rel) if isinstance(rel, list) else rel
            share = e["explained_variance"]
            lines.append(f"   {k}. {e['name'].replace('_', ' ')} on "
                         f"{_joint_list(e['joints'])}: {e['description']}.")
            folds = ev.get("folds_improved")
            folds = min(folds) if isinstance(folds, list) else folds
            lines.append(
                f"      It explains {100 * (share or 0):.0f} % of the nominal residual on those "
                f"joints. Evidence: {e['confidence']} (held-out error of its joints "
                f"{100 * (rel or 0):.0f} % lower, lower in {folds} folds, "
                f"t = {t_min if t_min is not None else float('inf'):.1f}).")
            lines += self._identified(e) + _stability_lines(e)
        if self.ambiguities:
            lines += ["", "   Not separable on these recordings:"]
            pairs = {}
            for a in self.ambiguities:
                if "text" in a:  # a group of confounded alternatives (stability.py)
                    lines.append(f"   - {a['text']}; {a['chosen']} is reported as the one "
                                 f"named most often. To separate them: {a['excitation']}.")
                    continue
                pairs.setdefault((a["effect"], a["alternative_effect"]), []).append(a)
            for (first, second), group in pairs.items():
                joints = sorted({j for a in group for j in a["joints"]})
                corr = min(abs(a["correlation"]) for a in group)
                lines.append(
                    f"   - ambiguous between {first.replace('_', ' ')} and "
                    f"{second.replace('_', ' ')} on {_joint_list(joints)} (correlation of their "
                    f"fitted terms {corr:.2f}{' or more' if corr < 0.995 else ''}); {first.replace('_', ' ')} is reported "
                    f"as the simpler. To separate them: "
                    f"{separating_excitation(first, second, joints)}.")
        if self.unidentifiable:
            lines += ["", "   Not identifiable from these recordings:"]
            for u in self.unidentifiable:
                lines.append(
                    f"   - the {u['effect'].replace('_', ' ')} of {_joint_list(u['joints'])}: "
                    f"a change smaller than {100 * u['smallest_change']:.0f} % cannot be told "
                    f"from a friction change of the joint ({100 * u['friction_share']:.1f} % "
                    "of its reference current is what friction terms reproduce); "
                    f"excitation needed: {u['excitation']}.")
        if self.implausible:
            lines += ["", "   Rejected estimates (not reported as findings):"]
            by_effect = {}
            for r in self.implausible:
                by_effect.setdefault(r["effect"], []).append(r)
            for name, group in by_effect.items():
                joints = sorted({j for r in group for j in r["joints"]})
                more = (f" (and {len(group) - 1} more like it)" if len(group) > 1 else "")
                lines.append(f"   - {name.replace('_', ' ')} on {_joint_list(joints)}: "
                             f"{group[0]['reason']}{more}.")
        if self.needs:
            lines += ["", "   What these recordings cannot show at a size that matters "
                          "(gpcd diagnose ... --plan plan.csv writes the recording to make):"]
            for n in self.needs:
                lines.append(f"   - {n['reason']}.")
        where = ("held-out recordings" if self.heldout else
                 "training recordings (in-sample: pass test recordings for a fair figure)")
        lines += ["", f"3. Fit before -> after, nMSE per joint while moving, on {where}:"]
        for j, (a, c) in enumerate(zip(self.nmse_before, self.nmse_after)):
            if a is None or c is None:
                lines.append(f"   joint {j + 1}: n/a")
                continue
            lines.append(f"   joint {j + 1}: nMSE {relative_change(a, c)}")
        return "\n".join(lines)

    def _identified(self, entry):
        """Lines on what the information matrix says of a named effect's entry."""
        rows = [r for r in self.identifiability if r["named"] and r["effect"] == entry["name"]
                and (r["target"] in entry["joints"] if entry["joints"] and r["target"]
                     is not None else True)]
        lines = []
        for r in rows:
            if r["confounded_with"]:
                other = r["confounded_with"][0]
                lines.append(f"      {r['label']}: correlated {other['correlation']:.2f} with "
                             f"{other['label']} in these recordings; smallest detectable "
                             f"{r['parameter']} {r['detectable']:.3g}.")
        return lines

    def __str__(self):
        return self.text()

    def plot(self, path=None):
        """The figure (see :func:`~sklearn_gpcd.diagnosis.plotting.plot_diagnosis`)."""
        from .plotting import plot_diagnosis

        return plot_diagnosis(self, path)


def _json_default(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)
