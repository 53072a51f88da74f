"""Scenarios, their analysis, the experiments of the paper's claims and the pages made from them."""
