"""The Tereshkov 2015 bias observer with the Tan et al. 2018 heading channel."""
