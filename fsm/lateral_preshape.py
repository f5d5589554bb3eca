"""The lateral pre-shape and its set-down as the task cycle asks for them (section 5.2, Coarse
Reach and a lateral regrasp): the search's inputs built from the running episode, the search
run (:func:`controllers.preshape.lateral_search.lateral_preshape`) and its result kept in the
episode; and the set-down questions Coarse Reach asks of a lateral goal
(:mod:`controllers.preshape.set_down_check`)."""

from __future__ import annotations

from controllers.preshape import lateral_search, set_down_check
from controllers.preshape.lateral_search import LateralSearchInputs, LateralSearchSettings
from controllers.preshape.set_down_check import SetDownGate
from controllers.reach.coarse import CoarseReachPlan
from fsm.config import TaskConfig
from fsm.context import Episode
from fsm.episode_queries import block_centre, block_site, reach_query, set_down_query


def search_settings(config: TaskConfig) -> LateralSearchSettings:
    """The lateral pre-shape search's settings from the task cycle's tuning."""
    return LateralSearchSettings(
        contacts=config.lateral_contacts,
        gate=config.lateral_gate,
        gate_rule=config.lateral_gate_rule,
        gate_four=config.lateral_gate_for(4),
        gate_three=config.lateral_gate_for(3),
        three_contacts=config.lateral_three_contacts,
        reserve_before_bands=config.lateral_reserve_before_bands,
        reserve_margin=config.lateral_reserve_margin,
        reserve_first=config.lateral_reserve_first,
        set_down_checks=config.lateral_grasp_set_down_checks,
        palm_pose=config.palm_pose,
    )


def search_inputs(ep: Episode) -> LateralSearchInputs:
    """The lateral pre-shape search's inputs for this cycle's block (no pre-shape taken yet:
    the reach test's contacts slide)."""
    return LateralSearchInputs(
        site=block_site(ep),
        palm_rotation=ep.coarse.goal.palm_rotation,
        query=reach_query(ep),
        load=ep.expected_load,
        centre=block_centre(ep),
        retry_floor=ep.retry_floor,
        set_down=set_down_query(ep),
    )


def lateral_preshape(ep: Episode, skip: int = 0, gate: SetDownGate | None = None) -> str | None:
    """The lateral pre-shape at the next palm pose beside the block (``skip``: the poses passed
    over; ``gate``: the set-down gate, default one of ``config.lateral_grasp_set_down_checks``),
    :func:`controllers.preshape.lateral_search.lateral_preshape`; the contacts the hand reached,
    the posture that took sampled ones and the wrist rolls to keep go into the episode
    (``preshape_contacts``, ``preshape_hand_q``, ``preshape_rolls``). Returns what was done, for
    the log, or None when no pose is approached without collision, or when a strict set-down
    ``gate`` was spent."""
    ep.preshape_contacts = None
    ep.preshape_hand_q = None
    ep.preshape_rolls = None
    taken = lateral_search.lateral_preshape(
        search_inputs(ep), search_settings(ep.config), skip, gate
    )
    ep.preshape_contacts = taken.contacts
    ep.preshape_hand_q = taken.hand_q
    ep.preshape_rolls = taken.rolls
    return taken.label


def pitched_at_least(ep: Episode, plan: CoarseReachPlan, floor: float) -> CoarseReachPlan | None:
    """The first lateral coarse reach to this cycle's block pitched ``floor`` (rad) or further
    down that has a path, chosen as ``plan`` was
    (:func:`controllers.preshape.set_down_check.pitched_at_least`); None when none has."""
    return set_down_check.pitched_at_least(ep.world, ep.target, ep.planning, plan, floor)


def pitch_for_set_down(ep: Episode, plan: CoarseReachPlan) -> tuple[CoarseReachPlan, str]:
    """``plan`` (a lateral coarse reach) when its goal's hand can set the block down at the
    place point, else the first plan pitched further down whose hand can, with why, for the log
    (:func:`controllers.preshape.set_down_check.pitch_for_set_down`; needs a place point)."""
    query = set_down_query(ep)
    if query is None:
        raise ValueError("a set-down is checked only towards a place point")
    return set_down_check.pitch_for_set_down(query, plan)
