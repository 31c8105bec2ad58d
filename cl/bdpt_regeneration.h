/* Course assignment 5 (postponed_regen) replaces this file: which sample each lane of BDPT's
 * regeneration launch starts (cl/bdpt_walk.h's bdpt_regenerate calls it). */
#ifndef BDPT_REGENERATION_H
#define BDPT_REGENERATION_H

#include "common.h"

/* Postponed regeneration (the talk's BDPT slides): the host waits until a share of the pool
 * (regenerate_fraction, 0.6) has terminated, compacts their slots into a list, and then one
 * launch restarts them all at once. Lane `lane` of that launch takes the lane-th listed slot: the
 * sample it starts there, r->first_id + lane while the budget lasts (the first r->fresh lanes;
 * consecutive ids, so consecutive pixels), or -1 when the budget is spent and the slot goes idle. */
HELPER int bdpt_regeneration_sample(const BdptRegeneration* r, int lane)
{
    return lane < r->fresh ? r->first_id + lane : -1;
}

#endif
