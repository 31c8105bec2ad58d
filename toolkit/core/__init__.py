"""The ground floor: the scene and its files, the records host and device share, the BVH, the film
and image files. Imports nothing else of the toolkit."""
