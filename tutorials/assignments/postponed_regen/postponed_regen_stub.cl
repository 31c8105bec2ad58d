/* Assignment 5: postponed regeneration (van Antwerpen, HPG 2011, BDPT slides). Your file replaces
 * the toolkit's cl/bdpt_regeneration.h, which cl/bdpt_walk.h's bdpt_regenerate calls:
 *     python -m toolkit grade postponed_regen --kernel THIS_FILE
 * bdpt_regeneration_sample, marked TODO, decides for each lane of the one regeneration launch
 * which sample that lane starts in its terminated slot, or that the slot goes idle. Keep its
 * name and arguments. */
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
    /* TODO: lane `lane` owns the lane-th terminated slot of the list. While the pass has samples
     * left (the first r->fresh lanes), return the id it starts: the ids follow r->first_id one by
     * one, in lane order. Past them, return -1 (the slot goes idle).
     * The placeholder starts the same sample in every slot: wrong, but every lane the host
     * counted writes its subpaths, so the other assignments' renders still run. */
    (void)lane;
    return r->first_id;
}

#endif
