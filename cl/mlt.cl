/* Metropolis light transport: many independent primary-sample-space chains (cl/mlt.h) whose
 * proposals are evaluated by bidirectional path tracing with the parallel connect phase. Built
 * with -DMLT=1, the BDPT kernels read their uniforms from the proposals (cl/bdpt_sampler.h): the walk
 * and connect code is the same code as bdpt_parallel_connect's, not a copy.
 * Kernels of one iteration, in order (toolkit/techniques/mlt.py):
 *   mlt_mutate                   cl/mlt_mutation.h           every chain writes its proposal
 *   bdpt_regenerate, bdpt_extend, bdpt_mark_terminated, the compaction,
 *   bdpt_parallel_connect_count, the scan, bdpt_parallel_connect
 *                                cl/bdpt_parallel_connect.cl  evaluate the proposals (one BDPT sample each)
 *   mlt_proposal_sums            cl/mlt_contribution.h       after each connect phase: each proposal's f and dims
 *   (the host reads the records for the splats)
 *   mlt_accept                   cl/mlt.h                    keep or reject each proposal
 * and once, for start = pool, after the candidates:
 *   mlt_start_from               cl/mlt.h                    each chain's first state, picked by the host */
#include "bdpt_parallel_connect.cl"
#include "mlt.h"
#include "mlt_contribution.h"
