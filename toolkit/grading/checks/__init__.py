"""The checks of each course assignment, one module per assignment, named after its folder in
tutorials/assignments/ (where the student's stub is). They are Python modules of the toolkit, not
files in that folder: there they would be importable only from an installed copy (as the data
package toolkit.assignments), and students would find the grader among their handouts."""
from toolkit.grading.checks import compaction, inplace_regen, mis, mlt_mutation, parallel_connect, postponed_regen

# In the order of the course, which is the talk's (tutorials/assignments/README.md): path tracing's
# in-place regeneration and compaction, then BDPT's parallel connect, MIS and postponed
# regeneration, then MLT's mutation.
ASSIGNMENTS = {a.name: a for a in (inplace_regen.ASSIGNMENT, compaction.ASSIGNMENT, parallel_connect.ASSIGNMENT,
                                   mis.ASSIGNMENT, postponed_regen.ASSIGNMENT, mlt_mutation.ASSIGNMENT)}
