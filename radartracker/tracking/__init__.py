"""Tracking: the TrackManager (admission, association, track life cycle) and the track-filter contract."""
