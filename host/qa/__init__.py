"""Quality assurance: a log graded per category, green, yellow or red, with the number and the fix."""
