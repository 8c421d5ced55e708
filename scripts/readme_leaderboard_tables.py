"""Copy results/leaderboard/leaderboard.md into the README's leaderboard section (python scripts/readme_leaderboard_tables.py)."""
import re
R="README.md"
s=open(R).read()
a=s.index("**lane-drop: `icv_envs/highway_formation-v0`")
b=s.index("### Training recipes and how far each target is")
md=open("results/leaderboard/leaderboard.md").read().strip("\n")
md=re.sub(r"^### (.*)$", r"**\1**", md, flags=re.M)
s=s[:a]+md+"\n\n"+s[b:]
open(R,"w").write(s)
