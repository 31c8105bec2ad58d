/* Where the BDPT random walk keeps its vertices: MAX_VERTICES per pool slot, slot after slot.
 * Index widths: the vertex index slot * MAX_VERTICES + k is an int (the host keeps it below
 * 2^31: toolkit/opencl/work_sizes.py buffer_plan), but the word offset of a vertex, VERTEX_WORDS (24)
 * times larger, would pass 2^31 at about 1.4M samples in flight (64 vertices each), so it is
 * formed in size_t. */
#ifndef VERTEX_MEMORY_H
#define VERTEX_MEMORY_H

#include "common.h"

#ifndef MAX_VERTICES
#error "MAX_VERTICES (vertices per subpath) comes from the host: toolkit/techniques/bdpt_evaluator.py walk_defines"
#endif
#if MAX_VERTICES < 2 || MAX_VERTICES > LONGEST_SUBPATH
#error "MAX_VERTICES must be 2 .. LONGEST_SUBPATH (toolkit/core/layout.py)"
#endif

#define VERTEX_WORDS ((int)(sizeof(BdptVertex) / sizeof(uint)))

/* Vertex k of the subpath of pool slot `slot`. */
HELPER int vertex_index(int slot, int k) { return slot * MAX_VERTICES + k; }

/* Word w of vertex `index` in the vertex memory seen as uint words. */
HELPER size_t vertex_word(int index, int w) { return (size_t)index * VERTEX_WORDS + w; }

#endif
