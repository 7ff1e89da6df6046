"""The catalogue of physical effects: one identity per effect, shared by the rig and the diagnosis.

Each entry says what the effect is (id, title, physics), where it lives on the virtual
dyno (`rig`: switchable with `dampnet rig --effects ID`, always on in the rig's base
physics, or absent), which diagnosis candidate detects it (`diagnosed_by`), and what a
model needs to capture it (`adds`: the features, feature parameters and terms
`dampnet train --add ID` adds). The rig's physics (dampnet.rig.effects.EFFECTS) and the
diagnosis's regressors (dampnet.diagnosis.catalogue.CANDIDATES) are keyed by these ids;
tests/python/test_effects_catalogue.py checks both sides against this list.

    gas_spring       rig: switchable   diagnosis: gas_spring
    thermal          rig: switchable   diagnosis: thermal
    valve_lag        rig: switchable   diagnosis: valve_lag
    friction         rig: switchable   diagnosis: friction
    bump_stop        rig: switchable   diagnosis: gas_spring (its position-dependent regressors
                                       include end-of-travel hinges; the same addition)
    compressibility  rig: always on (TruthParams.compressibility_tau_s, 2 ms: every real
                     damper has it, so switching it off would change every dataset)
                     diagnosis: compressibility
    mr_hysteresis    rig: absent       diagnosis: mr_hysteresis (an MR damper's pre-yield loop, growing with
                                       the control; added as gas_spring is: the displacement input)
    mount_hysteresis rig: switchable   diagnosis: none (no candidate: the diagnosis must say
                                       "structure left, not a known effect", dampnet.diagnosis.leftover)
    campaign_warming rig: switchable   diagnosis: none (thermal without a temperature channel: found as
                                       the run-order artefact, dampnet.data.artefacts)

The last two are there so that the diagnosis meets what a lab meets and no catalogue names.
Measurement artefacts (a channel delay, a sign or unit slip, a sensor offset, a drift over the
run order) are not physics: their family is dampnet.data.artefacts.

Add your own effect here first (`register_effect`), then its rig physics
(dampnet.rig.effects.register) and/or its diagnosis candidate
(dampnet.diagnosis.catalogue.register_candidate).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, Mapping

from dampnet import _core
from dampnet.features import Dahl, lags_of, with_state

#: switchable: `dampnet rig --effects ID`; always_on: part of the rig's base physics; absent: not simulated
RigRole = Literal["switchable", "always_on", "absent"]
RIG_ROLES: tuple[str, ...] = ("switchable", "always_on", "absent")


@dataclass(frozen=True)
class Estimate:
    """How an estimated parameter of the effect sets the feature parameter of its derived feature.

    `name` is the diagnosis's parameter (e.g. "tau_s" [s], "presliding_length_mm" [mm]),
    `per_si` how many of its units make the feature parameter's SI unit (1000 mm per m),
    `default` the feature parameter [SI] used when nothing was estimated.
    """

    name: str
    default: float
    per_si: float = 1.0


@dataclass(frozen=True)
class LagOf:
    """The registry's first-order lag of a base feature ("{control}": the data's control channel):
    derived features are named in dampnet.h and features.py only, found here by what they are."""

    source: str

    def resolve(self, control: str) -> str:
        source = self.source.format(control=control)
        names = lags_of(source)
        if not names:
            raise ValueError(f"no derived feature is a lag of {source!r} (dampnet.features)")
        return names[0]


@dataclass(frozen=True)
class StateOf:
    """The registry's derived feature carrying a state of this kind (e.g. features.Dahl)."""

    kind: type

    def resolve(self, control: str) -> str:
        names = with_state(self.kind)
        if not names:
            raise ValueError(f"no derived feature has a {self.kind.__name__} state (dampnet.features)")
        return names[0]


@dataclass(frozen=True)
class Additions:
    """What a model needs to capture an effect. `features` are base feature names (which may name
    "{control}", the data's control channel: voltage or current) or LagOf / StateOf for derived ones; `estimate` sets the parameter of the one derived
    feature among them; `terms` are physics terms (dampnet.terms) as dicts."""

    features: tuple[str | LagOf | StateOf, ...]
    how: str
    why: str
    estimate: Estimate | None = None
    terms: tuple[dict, ...] = ()


@dataclass(frozen=True)
class EffectInfo:
    id: str
    title: str
    physics: str
    rig: RigRole
    diagnosed_by: str | None  # the diagnosis candidate that detects it (None: none does)
    adds: Additions | None    # None: no recipe for adding it to a model

    def rig_words(self) -> str:
        return {"switchable": f"switch on with `dampnet rig --effects {self.id}`",
                "always_on": "always on in the rig's base physics",
                "absent": "not simulated by the rig"}[self.rig]


CATALOGUE: dict[str, EffectInfo] = {}


def register_effect(info: EffectInfo) -> EffectInfo:
    """Add (or replace) an effect in the catalogue; ValueError for an unknown rig role."""
    if info.rig not in RIG_ROLES:
        raise ValueError(f"effect {info.id!r}: rig must be one of {', '.join(RIG_ROLES)}, got {info.rig!r}")
    CATALOGUE[info.id] = info
    return info


def effect(effect_id: str) -> EffectInfo:
    """The catalogue entry of `effect_id`; ValueError listing the known ids."""
    try:
        return CATALOGUE[effect_id]
    except (KeyError, TypeError):
        raise ValueError(f"unknown effect {effect_id!r}: expected one of {', '.join(sorted(CATALOGUE))}") from None


def additions(effect_id: str, params: Mapping[str, Any] | None = None, control: str = "voltage") -> dict[str, Any]:
    """What `dampnet train --add EFFECT` adds: {"features", "terms", "feature_params", "how", "why"}.

    `params` are the effect's estimated parameters (the diagnosis's, e.g. {"tau_s": 0.013}
    for valve_lag); without the one the recipe reads, its default is used. `control` is
    the data's control channel. ValueError for an unknown effect or one without a recipe.
    """
    e = effect(effect_id)
    if e.adds is None:
        raise ValueError(f"effect {effect_id!r} has no recipe for adding it to a model")
    a = e.adds
    features = [f.format(control=control) if isinstance(f, str) else f.resolve(control) for f in a.features]
    feature_params: dict[str, float] = {}
    if a.estimate is not None:
        keys = [k for k in (_core.FEATURE_PARAMS.get(f) for f in features) if k]
        if len(keys) != 1:
            raise ValueError(f"effect {effect_id!r}: its features {features} need {len(keys)} feature "
                             "parameters, expected one for its estimate")
        value = (params or {}).get(a.estimate.name)
        feature_params[keys[0]] = (float(a.estimate.default) if value is None
                                   else float(value) / a.estimate.per_si)
    return {"features": features, "terms": [dict(t) for t in a.terms], "feature_params": feature_params,
            "how": a.how, "why": a.why.format(control=control)}


# -- the built-in effects ------------------------------------------------------------------

_POSITION = Additions(
    features=("displacement",), how="feature",
    why="displacement as an MLP input: the network learns a gas spring of any polytropic shape and "
        "end-of-travel stops together; a cubic position_poly term cannot follow a bump stop's sharp onset")

register_effect(EffectInfo(
    id="gas_spring", title="position-dependent force (gas spring, top-out, bump stops)",
    physics="The gas charge behind the floating piston is compressed polytropically as the rod enters "
            "(p V^n = const), so the force grows with position; elastomer bump stops and top-out "
            "springs add steep forces near the ends of travel. None of it depends on velocity.",
    rig="switchable", diagnosed_by="gas_spring", adds=_POSITION))

register_effect(EffectInfo(
    id="bump_stop", title="elastomer bump stop near full compression",
    physics="A polyurethane bump stop on the rod engages in the last millimetres of compression travel "
            "and adds a steep, progressive force that depends on position (and, with its hysteresis, "
            "on the direction of motion), not on velocity alone.",
    rig="switchable", diagnosed_by="gas_spring", adds=_POSITION))

register_effect(EffectInfo(
    id="thermal", title="oil viscosity changing with temperature",
    physics="Damper oil loses about half its viscosity per 20 K; the laminar (viscous) part of the "
            "pressure drop, so the damping force, falls as the oil warms, between tests and as a "
            "test heats it.",
    rig="switchable", diagnosed_by="thermal",
    adds=Additions(features=("temperature",), how="feature",
                   why="temperature as an MLP input: the viscosity law (Andrade, Walther) "
                       "and which part of the force it scales are learned from the data")))

register_effect(EffectInfo(
    id="valve_lag", title="control dynamics: valve or coil lag",
    physics="A solenoid valve's spool or an MR coil's field (inductance, eddy currents) follows the "
            "command with a time constant of milliseconds to tens of milliseconds, so after a step the "
            "force keeps the old damping for a while.",
    rig="switchable", diagnosed_by="valve_lag",
    adds=Additions(features=(LagOf("{control}"),), how="feature", estimate=Estimate("tau_s", 0.02),
                   why="the {control} after a first-order lag (estimated time constant) as an "
                       "extra MLP input: the network maps the valve's actual state to force; "
                       "the runtime carries one filter state")))

register_effect(EffectInfo(
    id="friction", title="seal friction and stick-slip near zero velocity",
    physics="Rod seals, the piston band and the wiper stick at velocity reversals: the friction force "
            "does not switch with the sign of velocity but builds up over a pre-sliding travel and "
            "may break away with a peak (Dahl, LuGre). A friction that is a function of velocity alone "
            "(Coulomb, Stribeck) is already within reach of a velocity-input model and is not credited here.",
    rig="switchable", diagnosed_by="friction",
    adds=Additions(features=(StateOf(Dahl),), how="feature",
                   estimate=Estimate("presliding_length_mm", 0.2 / 1000.0, per_si=1000.0),
                   why="the Dahl friction state as an MLP input: the network scales it and "
                       "combines it with velocity; the runtime carries one state")))

register_effect(EffectInfo(
    id="compressibility", title="force lagging velocity (oil compressibility, gas entrainment)",
    physics="The chamber pressure builds through the oil's effective bulk modulus (lowered by entrained "
            "gas and tube compliance), so the force lags the velocity by a time constant V/beta * dp/dQ; "
            "an acceleration input explains a small, linear lag, not a large or nonlinear one.",
    rig="always_on", diagnosed_by="compressibility",
    adds=Additions(features=(LagOf("velocity"),), how="feature", estimate=Estimate("tau_s", 0.002),
                   why="the velocity after a first-order lag as an extra MLP input: the network "
                       "learns how much of the force follows the lagged flow")))

register_effect(EffectInfo(
    id="mr_hysteresis", title="MR pre-yield hysteresis growing with the control",
    physics="In an MR damper the fluid in the valve gap is a Bingham solid below its yield stress, which the "
            "coil's field (the current) raises: after each reversal the force builds up elastically over "
            "millimetres of travel before the fluid yields and flows (the Bouc-Wen element of Spencer, Dyke, Sain "
            "and Carlson 1997, whose loop height alpha = alpha_a + alpha_b u grows with the control). The force "
            "depends on position and on the direction of motion, and the loop is larger at high control: "
            "unlike a rubber mount's, which is the same at every control.",
    rig="absent", diagnosed_by="mr_hysteresis",
    adds=Additions(features=("displacement",), how="feature",
                   why="displacement as an MLP input: with velocity and the control the network learns a "
                       "force that depends on position, the direction of motion and the control (the "
                       "pre-yield loop), as it learns a gas spring")))

register_effect(EffectInfo(
    id="mount_hysteresis", title="top-mount (bushing) rubber hysteresis in the load path",
    physics="The rubber of a top mount or eye bushing between the damper and the load cell has a "
            "rate-independent hysteresis (Bouc-Wen): a force that builds up over millimetres of travel "
            "after each reversal and saturates, the same at every frequency and control. No catalogue "
            "candidate models it: the diagnosis must find it as structure left that no known effect explains.",
    rig="switchable", diagnosed_by=None, adds=None))

register_effect(EffectInfo(
    id="campaign_warming", title="oil warming over the test campaign, no temperature logged",
    physics="The oil warms from test to test through a campaign (run order) while the rig logs no "
            "temperature: the viscous force falls along the run order. The thermal candidate needs a "
            "temperature channel to see differences between tests; without one the diagnosis finds it "
            "as a drift over the run order (dampnet.data.artefacts: run_order_drift).",
    rig="switchable", diagnosed_by=None, adds=None))
