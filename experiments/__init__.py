"""Studies that are not shipped controllers: the from-scratch PPO baseline on the raw env (``raw_ppo``, its
learning curve ``raw_ppo_plots``; command line ``scripts/train_raw_ppo.py``) and where an episode's cross-track
error is made (``cross_track_budget``; ``scripts/cross_track_budget.py``). They build on ``agents``; nothing in the
package imports them."""
