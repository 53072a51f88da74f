"""The gait side of a re-plan: set-point, crawl schedule and footholds, touchdown rule, speed
feedback, swing trajectory."""
