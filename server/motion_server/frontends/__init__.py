"""Protocol front-ends: thin adapters from requests to tag-image reads and writes."""
