#version 450 core
flat in uint v_site;
layout(location = 0) out uint o_site;
void main() { o_site = v_site; }
