"""The course assignments' grader."""
