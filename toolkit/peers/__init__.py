"""Peer renderers the toolkit is measured against: Embree (ray queries) and Mitsuba 3 (images, speed)."""
