"""The laser pointer (issue 5): a laser spot on a calibrated screen moves the pointer.

``spot`` finds at most one laser spot per camera frame (image pixels, sub-pixel).
"""
