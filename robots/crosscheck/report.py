"""The result of a Pinocchio-vs-MuJoCo dynamics cross-check: per-quantity errors, what was left out.

A ``Report`` holds one ``QuantityResult`` per compared quantity and one ``FeatureNote`` per model
feature MuJoCo simulates but Pinocchio does not (contacts, limits, damping, tendons, ...), with
how each was handled: "excluded" (switched off for the comparison; the rigid-body quantities
remain a fair comparison), "accounted" (corrected for explicitly) or "not compared" (the plant
does something the Pinocchio model cannot reproduce, so no pass is claimed for it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

#: Status values of a quantity.
PASS, FAIL, NOT_COMPARED = "pass", "fail", "not compared"
#: Handling of a model feature.
EXCLUDED, ACCOUNTED = "excluded", "accounted"


class QuantityResult(NamedTuple):
    """Errors of one quantity over all states, Pinocchio value ``a`` against MuJoCo value ``b``.

    Attributes:
        name: Quantity name, e.g. "mass_matrix" (see ``mbctl.robots.crosscheck.TOLERANCES``).
        description: What was compared, with its frame and unit.
        unit: SI unit of the errors ("-" for dimensionless).
        max_abs_error: ``max_s max_i |a_si - b_si|`` [unit]; inf when a value was not finite.
        max_rel_error: ``max_abs_error / max(max_s max_i |b_si|, floor)`` [-].
        tolerance: Largest passing ``max_rel_error`` [-].
        floor: Magnitude [unit] below which the quantity counts as zero (see TOLERANCES).
        worst_state: Index of the state with the largest absolute error (-1 if not compared).
        worst_state_kind: What kind of state that is ("random", "zero velocity", ...).
        status: "pass", "fail" or "not compared".
        note: Why a quantity was not compared or failed structurally, or what it covers or how
            each side computes it (``Tolerance.method``); "" otherwise.
        worst_entry: For a failing quantity, where in the worst state the largest error is
            (frame, joint of the velocity coordinate, axis), e.g. "body 'link2', axis z";
            "" when it passed, is a scalar, or the place is unknown.
    """

    name: str
    description: str
    unit: str
    max_abs_error: float
    max_rel_error: float
    tolerance: float
    floor: float
    worst_state: int
    worst_state_kind: str
    status: str
    note: str = ""
    worst_entry: str = ""

    @property
    def passed(self) -> bool:
        """Whether the quantity was compared and is within tolerance."""
        return self.status == PASS

    @property
    def reason(self) -> str:
        """Why the quantity failed: its errors, the tolerance and where; "" unless it failed."""
        if self.status != FAIL:
            return ""
        if self.worst_state < 0:  # not evaluated state by state (the structure check)
            return f"{self.name} failed: {self.note}"
        where = f"state {self.worst_state} ({self.worst_state_kind})"
        if self.worst_entry:
            where += f", {self.worst_entry}"
        if not math.isfinite(self.max_abs_error):
            return (
                f"{self.name} failed: a value is not finite (NaN or inf) at {where}; "
                f"tolerance {self.tolerance:.1e}"
            )
        return (
            f"{self.name} failed: max rel error {self.max_rel_error:.3e} > tolerance "
            f"{self.tolerance:.1e}; max abs error {self.max_abs_error:.3e} {self.unit} at {where}"
        )


class FeatureNote(NamedTuple):
    """A model feature outside the rigid-body comparison and how it was handled.

    Attributes:
        feature: Feature name, e.g. "frictionloss" or "tendons".
        handling: "excluded", "accounted" or "not compared".
        detail: What the model has (counts, values) and why it was handled this way.
    """

    feature: str
    handling: str
    detail: str


def _json_float(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


@dataclass(frozen=True)
class Report:
    """A cross-check report.

    Attributes:
        robot: Robot name.
        pin_model_file: File the Pinocchio model came from.
        mj_model_file: File the MuJoCo model came from.
        n_states: Number of states evaluated (random plus edge states).
        seed: Seed of the random states.
        state_kinds: Count of states per kind, e.g. {"random": 100, "zero velocity": 2}.
        quantities: One result per quantity, in a fixed order.
        features: Model features outside the rigid-body comparison and their handling.
        notes: Other findings (load-time agreement check, frames without a counterpart).
        elapsed_s: Wall-clock time of the evaluation [s] (sampling and model preparation excluded).
        edits: Load-time edits of the models (``ModelSource.edits``): gravity, the Pinocchio
            file, and how its joints were paired with the plant's (renamed, reordered, a free
            flyer added).
    """

    robot: str
    pin_model_file: str
    mj_model_file: str
    n_states: int
    seed: int
    state_kinds: dict[str, int]
    quantities: tuple[QuantityResult, ...]
    features: tuple[FeatureNote, ...] = field(default=())
    notes: tuple[str, ...] = field(default=())
    elapsed_s: float = 0.0
    edits: tuple[str, ...] = field(default=())

    @property
    def passed(self) -> bool:
        """True when no compared quantity failed and at least one was compared.

        Features reported as "not compared" do not make a report fail, but they are not passed
        either: see ``not_compared`` and ``complete``.
        """
        compared = [q for q in self.quantities if q.status != NOT_COMPARED]
        return bool(compared) and all(q.passed for q in compared)

    @property
    def failed(self) -> tuple[str, ...]:
        """Names of the quantities that failed."""
        return tuple(q.name for q in self.quantities if q.status == FAIL)

    @property
    def not_compared(self) -> tuple[str, ...]:
        """Names of quantities and features that were not compared."""
        return tuple(q.name for q in self.quantities if q.status == NOT_COMPARED) + tuple(
            f.feature for f in self.features if f.handling == NOT_COMPARED
        )

    @property
    def complete(self) -> bool:
        """Whether everything the plant simulates was either compared or honestly excluded."""
        return not self.not_compared

    @property
    def states_per_second(self) -> float:
        """Evaluation throughput [states/s]."""
        return self.n_states / self.elapsed_s if self.elapsed_s > 0 else math.inf

    def quantity(self, name: str) -> QuantityResult:
        """The result of quantity ``name``; KeyError lists the available names."""
        for q in self.quantities:
            if q.name == name:
                return q
        raise KeyError(f"No quantity {name!r}; available: {', '.join(q.name for q in self.quantities)}")

    @property
    def verdict(self) -> str:
        """One word (plus qualifier): "PASS", "FAIL" or "PASS (incomplete: ...)"."""
        if not self.passed:
            return "FAIL"
        if not self.complete:
            return f"PASS (incomplete: not compared: {', '.join(self.not_compared)})"
        return "PASS"

    def to_dict(self) -> dict[str, Any]:
        """The report as JSON-able built-in types (non-finite numbers become None)."""
        return {
            "robot": self.robot,
            "pin_model_file": self.pin_model_file,
            "mj_model_file": self.mj_model_file,
            "n_states": self.n_states,
            "seed": self.seed,
            "state_kinds": dict(self.state_kinds),
            "passed": self.passed,
            "complete": self.complete,
            "verdict": self.verdict,
            "failed": list(self.failed),
            "not_compared": list(self.not_compared),
            "quantities": [
                {
                    "name": q.name,
                    "description": q.description,
                    "unit": q.unit,
                    "max_abs_error": _json_float(q.max_abs_error),
                    "max_rel_error": _json_float(q.max_rel_error),
                    "tolerance": q.tolerance,
                    "floor": q.floor,
                    "worst_state": q.worst_state,
                    "worst_state_kind": q.worst_state_kind,
                    "status": q.status,
                    "note": q.note,
                    "worst_entry": q.worst_entry,
                    "reason": q.reason,
                }
                for q in self.quantities
            ],
            "features": [f._asdict() for f in self.features],
            "notes": list(self.notes),
            "edits": list(self.edits),
            "elapsed_s": self.elapsed_s,
            "states_per_second": _json_float(self.states_per_second),
        }

    def to_text(self) -> str:
        """A plain-text table of the quantities followed by the feature handling and notes.

        Under each failing row, a line says why it failed (``QuantityResult.reason``).
        """
        kinds = ", ".join(f"{n} {k}" for k, n in self.state_kinds.items())
        lines = [
            f"cross-check of {self.robot}: Pinocchio ({self.pin_model_file}) vs MuJoCo "
            f"({self.mj_model_file})",
            f"{self.n_states} states ({kinds}), seed {self.seed}, "
            f"{self.elapsed_s:.3f} s ({self.states_per_second:.0f} states/s)",
            "convention: Pinocchio's (free-flyer velocity in the base frame; Jacobians LOCAL_WORLD_ALIGNED)",
            "errors: abs = max over states and entries of |Pinocchio - MuJoCo|; "
            "rel = abs / max(max |MuJoCo|, floor); pass when rel <= tolerance",
            "",
            f"{'quantity':20s} {'unit':10s} {'max abs err':>12s} {'max rel err':>12s} "
            f"{'tolerance':>10s} {'worst':>6s}  {'state kind':16s} result",
        ]
        for q in self.quantities:
            if q.status == NOT_COMPARED:
                lines.append(
                    f"{q.name:20s} {q.unit:10s} {'-':>12s} {'-':>12s} {q.tolerance:10.1e} "
                    f"{'-':>6s}  {'-':16s} NOT COMPARED ({q.note})"
                )
                continue
            lines.append(
                f"{q.name:20s} {q.unit:10s} {q.max_abs_error:12.3e} {q.max_rel_error:12.3e} "
                f"{q.tolerance:10.1e} {q.worst_state:6d}  {q.worst_state_kind:16s} "
                f"{q.status.upper()}"
            )
            if q.status == FAIL:
                lines.append(f"    -> {q.reason}")
            elif q.note and q.worst_state >= 0:  # how a compared quantity is computed
                lines.append(f"    ({q.note})")
        if self.features:
            lines += ["", "model features outside the rigid-body comparison:"]
            lines += [f"  {f.feature:22s} {f.handling.upper():13s} {f.detail}" for f in self.features]
        if self.edits:
            lines += ["", "load-time edits:"]
            lines += [f"  - {e}" for e in self.edits]
        if self.notes:
            lines += ["", "notes:"]
            lines += [f"  - {n}" for n in self.notes]
        lines += ["", f"result: {self.verdict}"]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.to_text()
