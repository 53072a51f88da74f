"""Bags: the mcap writer and reader, and the recovery of a killed recorder's bag."""
