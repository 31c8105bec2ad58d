/* Metropolis light transport: many independent primary-sample-space chains (cl/mlt.h) whose
 * proposals are evaluated by bidirectional path tracing with the parallel connect phase. Built
 * with -DMLT=1, the BDPT kernels read their uniforms from the proposals (cl/bdpt_sampler.h): the walk
 * and connect code is the same code as bdpt_parallel_connect's, not a copy.
 * Kernels of one iteration, in order (toolkit/techniques/mlt.py):
 *   mlt_mutate                   cl/mlt_mutation.h           every chain writes its proposal
 *   bdpt_regenerate, bdpt_extend, bdpt_mark_terminated, the compaction,
 *   bdpt_parallel_connect_count, the scan, bdpt_parallel_connect
 *                                cl/bdpt_parallel_connect.cl  evaluate the proposals (one BDPT sample each)
 *   mlt_proposal_sums            cl/mlt_contribution.h       after each connect phase: each proposal's f and dims,
 *                                                            its records into the proposal store
 *   mlt_accept_and_weigh         cl/mlt_splat.h, cl/mlt.h    each chain's splat weights and the large steps' f
 *                                                            into b, then keep or reject each proposal
 *   mlt_weigh_records, record_film_add (x3)                  the splats into the films (cl/record_film.cl)
 *   mlt_keep_records             cl/mlt_splat.h              the next current states' records; b for the next
 *                                                            iteration's weights (work-item 0)
 * and once, for start = pool, after the candidates (one batch of BDPT samples, each one's records kept):
 *   mlt_candidates_into_b        cl/mlt_start.h              every candidate's f into b
 *   mlt_estimate_first_b         cl/mlt_start.h              b for the first iteration's weights
 *   mlt_start_from               cl/mlt_start.h              each chain's first state, picked by the host
 * or for start = resample:
 *   mlt_resample_weights         cl/mlt_splat.h              each chain's weight
 * The splats are added by the record film's own program (cl/record_film.cl, toolkit/opencl/record_film.py). */
#include "bdpt_parallel_connect.cl"
#include "mlt.h"
#include "mlt_contribution.h"
#include "mlt_splat.h"
#include "mlt_start.h"
